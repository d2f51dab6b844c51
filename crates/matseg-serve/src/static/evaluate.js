// The evaluate page: runs `matseg eval points` on a benchmark folder given
// to `matseg serve --bench`, for the served model and the ticked
// baselines, and shows the All / Soft / top-1 table, each image's scores,
// and an image's points with the model's similarity map to any of them.

import { api, similarities, bitmap, blend, ring, pointOf, COLOUR_MAPS, PALETTE, listFolders } from "/common.js";

const DEFAULT_BASELINES = ["rgb", "lab", "texture", "position"];
const COLUMNS = [["all_by_material", "All by material"], ["all_by_point", "All by point"],
  ["soft_by_material", "Soft by material"], ["soft_by_point", "Soft by point"],
  ["top1_by_material", "Top-1 by material"], ["top1_by_point", "Top-1 by point"]];
const status = document.getElementById("status");
const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d", { willReadFrequently: true });
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
  status.textContent = `${c.images} images (${c.soft_images} with relations), ${c.points} points`
    + (report.skipped.length ? `; skipped: ${report.skipped.join("; ")}` : "");
  document.getElementById("scores").dataset.done = "1";
}

async function poll() {
  const answer = await (await api("/api/evaluate", { root: state.root })).json();
  if (answer.state === "running") {
    const model = answer.model ? `${answer.model}: ` : "";
    const images = answer.total ? `${answer.done} of ${answer.total} images of all models, ` : "";
    status.textContent = `evaluating in the background... ${model}${images}${Math.round(answer.seconds)} s`;
    setTimeout(poll, 1000);
  } else if (answer.state === "done") {
    showReport(answer.report);
  } else if (answer.state === "failed") {
    status.textContent = answer.error;
  } else if (answer.state === "cancelled") {
    status.textContent = "The evaluation was cancelled.";
  }
  document.getElementById("run").disabled = answer.state === "running";
  document.getElementById("cancel").hidden = answer.state !== "running";
}

document.getElementById("cancel").addEventListener("click", async () => {
  try {
    await api("/api/evaluate", { root: state.root }, { method: "DELETE" });
  } catch (error) {
    status.textContent = error.message;
  }
});

document.getElementById("run").addEventListener("click", async () => {
  const baselines = [...document.querySelectorAll("#baselines input:checked")].map((b) => b.value);
  try {
    await api("/api/evaluate", { root: state.root, baselines: baselines.join(",") }, { method: "POST" });
    poll();
  } catch (error) {
    status.textContent = error.message;
  }
});

function drawView() {
  const view = state.view;
  context.drawImage(view.image, 0, 0);
  if (view.values) blend(context, (i) => COLOUR_MAPS.red(view.values[i]), 0.7);
  view.groups.forEach((group, g) => {
    for (const [x, y] of group.points) ring(context, x, y, PALETTE[g % PALETTE.length]);
  });
  if (view.chosen) ring(context, view.chosen[0], view.chosen[1], [255, 255, 255], 10);
}

async function openImage(name) {
  try {
    const saved = await (await api("/api/annotation", { root: state.root, name })).json();
    const image = await bitmap(await api("/api/photo", { root: state.root, path: saved.path }));
    state.view = { name, path: saved.path, image, groups: saved.groups, values: null, chosen: null };
    canvas.width = image.width;
    canvas.height = image.height;
    canvas.hidden = false;
    canvas.dataset.image = name;
    drawView();
    canvas.scrollIntoView({ block: "nearest" });
  } catch (error) {
    status.textContent = error.message;
  }
}

canvas.addEventListener("click", async (event) => {
  const view = state.view;
  if (!view) return;
  const [x, y] = pointOf(canvas, event);
  const nearest = view.groups.flatMap((g) => g.points)
    .map(([px, py, r]) => ({ px, py, r, d: Math.hypot(px - x, py - y) }))
    .sort((a, b) => a.d - b.d)[0];
  if (!nearest) return;
  view.values = await similarities(await api("/api/similarity",
    { root: state.root, path: view.path, points: `${nearest.px},${nearest.py}`, radius: nearest.r }));
  view.chosen = [nearest.px, nearest.py];
  drawView();
  canvas.dataset.answered = String(Number(canvas.dataset.answered || 0) + 1);
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
  status.textContent = "No benchmark: start the server with --bench FOLDER.";
}
