"""What the parts of the package that need PyTorch check before anything
else, so that a missing torch, or a matseg built without libtorch, is
said in one line that says what to install.

`import matseg` itself, `matseg.Model` (describe, similarity, select,
cluster, track), `matseg.evaluate`, `matseg.Generator` and `matseg.Dataset`
need neither: they run on the pure-Rust engine.
"""

import importlib.util

from . import _core

#: How to get the PyTorch these parts are written for.
INSTALL_TORCH = "pip install torch==2.11.0"

#: How to build matseg with libtorch, from the repository's root.
BUILD_WITH_TORCH = "MATURIN_PEP517_ARGS='--features torch' pip install './python[torch]'"


def libtorch_build(what: str) -> None:
    """Raises ImportError when this matseg was built without libtorch (the
    native module's `torch` feature), which `what` needs."""
    if not _core.WITH_TORCH:
        raise ImportError(f"{what} needs matseg built with libtorch; this one was built without: {BUILD_WITH_TORCH}")


def torch(what: str) -> None:
    """Raises ModuleNotFoundError when PyTorch is not installed, and
    ImportError when this matseg was built without libtorch: `what` needs
    both."""
    if importlib.util.find_spec("torch") is None:
        raise ModuleNotFoundError(
            f"{what} needs PyTorch, which is not installed: {INSTALL_TORCH}, "
            f"and matseg built with it: {BUILD_WITH_TORCH}",
            name="torch",
        )
    libtorch_build(what)
