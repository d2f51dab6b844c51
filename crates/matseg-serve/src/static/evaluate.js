// The evaluate page: runs `matseg eval points` on a benchmark folder given
// to `matseg serve --bench`, for the served model and the ticked
// baselines, and shows each model's images scored as it runs (and the
// names of the model's), then the All / Soft / top-1 table, each image's
// scores, and an image's points with the model's similarity map to any of
// them, in the segment page's views: a colour unlike the photo, red or a
// heat map, or the photo greyed under cyan.

import { api, readPixels, bitmap, ring, pointOf, say, strength, COLOUR_MAPS, PALETTE, colourTable, Layer,
  paintByRed, greyCopy, contrastingTint, listFolders } from "/common.js";

const DEFAULT_BASELINES = ["rgb", "lab", "texture", "position"];
const COLUMNS = [["all_by_material", "All by material"], ["all_by_point", "All by point"],
  ["soft_by_material", "Soft by material"], ["soft_by_point", "Soft by point"],
  ["top1_by_material", "Top-1 by material"], ["top1_by_point", "Top-1 by point"]];
const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d");
const [mode, opacity] = ["view-mode", "opacity"].map((id) => document.getElementById(id));
const layer = new Layer();
// view: the image open, its points, and the map shown (`map`: the
// similarity PNG's pixels), its greyed copy and its contrasting tint.
const state = { root: null, images: [], view: null };

const score = (v) => (v === null || v === undefined ? "-" : v.toFixed(4));

function row(cells, header = false) {
  const tr = document.createElement("tr");
  for (const cell of cells) {
    const td = document.createElement(header ? "th" : "td");
    td.textContent = cell;
    tr.append(td);
  }
  return tr;
}

function showReport(report) {
  document.getElementById("scores").replaceChildren(row(["model", ...COLUMNS.map(([, t]) => t)], true),
    ...report.models.map((m) => row([m.model, ...COLUMNS.map(([key]) => score(m[key]))])));
  const models = report.models;
  const table = document.getElementById("images");
  table.replaceChildren(row(["image", ...models.map((m) => `${m.model}: All / Soft`)], true));
  models[0].images.forEach((image, i) => {
    const tr = row([image.name, ...models.map((m) =>
      `${score(m.images[i].all_by_material)} / ${score(m.images[i].soft_by_material)}`)]);
    tr.classList.add("pick");
    tr.dataset.name = image.name;
    tr.addEventListener("click", () => openImage(image.name));
    table.append(tr);
  });
  const c = models[0].counts;
  say(`${c.images} images (${c.soft_images} with relations), ${c.points} points`
    + (report.skipped.length ? `; skipped: ${report.skipped.join("; ")}` : ""));
  document.getElementById("scores-heading").hidden = false;
  document.getElementById("scores").dataset.done = "1";
}

// The running evaluation's progress: each model's images scored (the
// served model, last, apart from the baselines), and the names of those
// the model being scored has finished, as they come.
function showProgress(answer) {
  const box = document.getElementById("progress");
  const models = answer.models ?? [];
  box.hidden = answer.state !== "running" || !models.length;
  if (box.hidden) return;
  document.getElementById("models").replaceChildren(...models.map((m, i) => {
    const item = document.createElement("li");
    const kind = i === models.length - 1 ? "the model" : "baseline";
    item.textContent = `${kind} ${m.model}: ${m.done} of ${m.total} images`;
    item.dataset.model = m.model;
    item.dataset.done = m.done;
    return item;
  }));
  const current = models.find((m) => m.done < m.total) ?? models[models.length - 1];
  const scored = answer.scored ?? [];
  document.getElementById("scored").textContent = scored.length
    ? `${current.model} has scored: ${scored.join(", ")}` : `${current.model}: describing the first image…`;
}

async function poll() {
  let answer;
  try {
    answer = await (await api("/api/evaluate", { root: state.root })).json();
  } catch (error) {
    say(error.message, true);
    return;
  }
  showProgress(answer);
  if (answer.state === "running") {
    const models = answer.models ?? [];
    const served = models[models.length - 1];
    const baselines = models.slice(0, -1);
    const count = (list, key) => list.reduce((n, m) => n + m[key], 0);
    const parts = [];
    if (baselines.length) parts.push(`baselines ${count(baselines, "done")} of ${count(baselines, "total")} images`);
    if (served) parts.push(`the model (${served.model}) ${served.done} of ${served.total}`);
    if (!parts.length && answer.total) parts.push(`${answer.done} of ${answer.total} images`);
    say(`evaluating in the background: ${parts.join("; ")}; ${Math.round(answer.seconds)} s`);
    setTimeout(poll, 250);
  } else if (answer.state === "done") {
    showReport(answer.report);
  } else if (answer.state === "failed") {
    say(answer.error, true);
  } else if (answer.state === "cancelled") {
    say("The evaluation was cancelled.");
  }
  document.getElementById("run").disabled = answer.state === "running";
  document.getElementById("cancel").hidden = answer.state !== "running";
}

document.getElementById("cancel").addEventListener("click", async () => {
  try {
    await api("/api/evaluate", { root: state.root }, { method: "DELETE" });
  } catch (error) {
    say(error.message, true);
  }
});

document.getElementById("run").addEventListener("click", async () => {
  const baselines = [...document.querySelectorAll("#baselines input:checked")].map((b) => b.value);
  try {
    await api("/api/evaluate", { root: state.root, baselines: baselines.join(",") }, { method: "POST" });
    poll();
  } catch (error) {
    say(error.message, true);
  }
});

// The map's colours by similarity (0..255) in the view chosen: a colour,
// with the strength the net was trained to read, or the heat map.
function mapColours(view) {
  const by = (rgb) => colourTable((v) => [...rgb, strength(v / 255)]);
  if (mode.value === "grey") return by([0, 255, 255]);
  if (mode.value === "solid") return by(view.solid);
  return colourTable((v) => COLOUR_MAPS[mode.value](v / 255));
}

// Redoes the map's layer in the view chosen, and redraws.
function paintMap() {
  const view = state.view;
  if (view?.map) {
    paintByRed(view.map.bytes, layer.words(view.map.width, view.map.height), mapColours(view));
    layer.put();
  }
  drawView();
}

function drawView() {
  const view = state.view;
  if (!view) return;
  const grey = view.map && mode.value === "grey";
  if (grey && !view.grey) view.grey = greyCopy(view.image);
  context.drawImage(grey ? view.grey : view.image, 0, 0);
  if (view.map) layer.drawOver(context, Number(opacity.value));
  view.groups.forEach((group, g) => {
    for (const [x, y] of group.points) ring(context, x, y, PALETTE[g % PALETTE.length]);
  });
  if (view.chosen) ring(context, view.chosen[0], view.chosen[1], [255, 255, 255], 10);
}
mode.addEventListener("input", paintMap);
opacity.addEventListener("input", drawView);

async function openImage(name) {
  try {
    const saved = await (await api("/api/annotation", { root: state.root, name })).json();
    const image = await bitmap(await api("/api/photo", { root: state.root, path: saved.path }));
    state.view = { name, path: saved.path, image, groups: saved.groups, map: null, grey: null, chosen: null,
      solid: contrastingTint(image) };
    canvas.width = image.width;
    canvas.height = image.height;
    canvas.hidden = false;
    canvas.dataset.image = name;
    drawView();
    canvas.scrollIntoView({ block: "nearest" });
    say(`${name}: click near one of its points for the model's similarity to it`);
  } catch (error) {
    say(error.message, true);
  }
}

canvas.addEventListener("pointerdown", async (event) => {
  const view = state.view;
  if (!view || event.button !== 0) return;
  const [x, y] = pointOf(canvas, event);
  const nearest = view.groups.flatMap((g) => g.points)
    .map(([px, py, r]) => ({ px, py, r, d: Math.hypot(px - x, py - y) }))
    .sort((a, b) => a.d - b.d)[0];
  if (!nearest) {
    say(`${view.name} has no annotated point to show the similarity of.`, true);
    return;
  }
  try {
    const map = await readPixels(await api("/api/similarity",
      { root: state.root, path: view.path, points: `${nearest.px},${nearest.py}`, radius: nearest.r }));
    if (state.view !== view) return;
    view.map = map;
    view.chosen = [nearest.px, nearest.py];
    paintMap();
    say(`${view.name}: the model's similarity to the point ${nearest.px}, ${nearest.py}`);
    canvas.dataset.answered = String(Number(canvas.dataset.answered || 0) + 1);
  } catch (error) {
    say(error.message, true);
  }
});

const { benches, baselines } = await (await api("/api/benches")).json();
document.getElementById("baselines").replaceChildren(...baselines.map((name) => {
  const label = document.createElement("label");
  label.innerHTML = `<input type="checkbox"> `;
  label.firstChild.value = name;
  label.firstChild.checked = DEFAULT_BASELINES.includes(name);
  label.append(name);
  return label;
}));
const select = document.getElementById("bench");
listFolders(select, benches);
select.addEventListener("change", () => {
  state.root = select.value;
  poll();
});
if (benches.length) {
  state.root = benches[0].root;
  poll();
} else {
  say("No benchmark: start the server with --bench FOLDER.", true);
}
