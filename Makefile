# The two entry points a newcomer needs (see README.md). Set-up steps (the
# project-local torch venv for the net: scripts/torch-env.sh; the headless
# Chromium of the web app's browser tests: scripts/chromium-env.sh) run
# behind them.

CARGO ?= cargo
DEMO_OUT ?= demo-out

.PHONY: demo test

## Run the whole pipeline on the bundled assets; open $(DEMO_OUT)/index.html.
demo:
	scripts/torch-env.sh
	$(CARGO) run --release -p matseg-cli -- demo --out $(DEMO_OUT)

## Formatting, lints and the whole test suite: exactly what CI runs.
test:
	bash .ci/run
