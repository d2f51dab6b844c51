// The annotate page: builds or edits a point benchmark in the MatSeg
// layout (a folder given to `matseg serve --bench`). Click adds a point
// to the active group, alt-click removes the nearest point; groups can be
// named and marked partly the same (0.6 or 0.3); undo steps back one edit.
// Opening another image (or leaving) with unsaved points asks first.
// Saving writes data/NAME/data.json and group_relations.txt, each file
// whole, and reopening the image shows what was saved. A group with no
// name of its own shows the one the benchmark's data/NAME/labels.json
// gives its id, when there is one.

import { api, bitmap, ring, pointOf, say, PALETTE, listFolders } from "/common.js";

const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d");
// labels: the material names of the image's labels.json, by group id.
const state = { root: null, name: null, image: null, annotation: null, labels: {}, active: 0, history: [], saved: "" };

const snapshot = () => JSON.stringify(state.annotation);

// Whether an image is open to annotate; says so when not.
function opened() {
  if (!state.annotation) say("Open an image of a benchmark first.", true);
  return state.annotation !== null;
}

function edit(change) {
  if (!opened()) return;
  state.history.push(snapshot());
  change(state.annotation);
  render();
}

function colourOf(index) {
  return PALETTE[index % PALETTE.length];
}

function render() {
  if (!state.image) return;
  context.drawImage(state.image, 0, 0);
  const { groups, relations } = state.annotation;
  groups.forEach((group, g) => {
    for (const [x, y, r] of group.points) {
      ring(context, x, y, colourOf(g), Math.max(4, r));
      context.fillStyle = `rgb(${colourOf(g).join(",")})`;
      context.fillRect(x - 1, y - 1, 3, 3);
    }
  });
  const list = document.getElementById("groups");
  list.replaceChildren(...groups.map((group, g) => {
    const item = document.createElement("li");
    item.classList.toggle("active", g === state.active);
    item.innerHTML = `<input type="checkbox" class="pick"> <span class="swatch"></span>
      <b></b> <input class="name" placeholder="name"> <span></span>`;
    item.querySelector("b").textContent = group.id;
    item.querySelector("span:last-child").textContent = `${group.points.length} pt`;
    item.querySelector(".swatch").style.background = `rgb(${colourOf(g).join(",")})`;
    const name = item.querySelector(".name");
    name.value = group.name ?? "";
    const label = state.labels[group.id];
    if (label) {
      name.placeholder = label;
      name.title = `${label} (labels.json)`;
    }
    // A name is kept as typed, without redrawing the list (which would
    // take away the field the user moves to next).
    name.addEventListener("change", () => {
      state.history.push(snapshot());
      state.annotation.groups[g].name = name.value;
      showStatus();
    });
    item.addEventListener("click", (event) => {
      if (event.target.tagName === "INPUT") return;
      state.active = g;
      render();
    });
    item.dataset.id = group.id;
    return item;
  }));
  document.getElementById("relations").replaceChildren(...relations.map((relation, r) => {
    const item = document.createElement("li");
    const [open, close] = relation.weight === 0.6 ? ["[", "]"] : ["(", ")"];
    item.textContent = `${open}${relation.ids.join(", ")}${close} `;
    const remove = document.createElement("button");
    remove.textContent = "remove";
    remove.addEventListener("click", () => edit((a) => a.relations.splice(r, 1)));
    item.append(remove);
    return item;
  }));
  showStatus();
}

const unsaved = () => state.annotation !== null && snapshot() !== state.saved;

function showStatus(suffix = "") {
  const { groups } = state.annotation;
  say(`${state.name}: ${groups.length} groups, ${groups.reduce((n, g) => n + g.points.length, 0)} points`
    + (unsaved() ? " (not saved)" : " (saved)") + suffix);
}

// Leaving the page with unsaved points asks first.
window.addEventListener("beforeunload", (event) => {
  if (unsaved()) event.preventDefault();
});

function newGroup(annotation) {
  const next = Math.max(0, ...annotation.groups.map((g) => Number(g.id))) + 1;
  annotation.groups.push({ id: String(next), name: "", points: [] });
  state.active = annotation.groups.length - 1;
}

// Points are taken when the button goes down (the primary one).
canvas.addEventListener("pointerdown", (event) => {
  if (!state.image || event.button !== 0) return;
  const [x, y] = pointOf(canvas, event);
  if (event.altKey) {
    let nearest = null;
    state.annotation.groups.forEach((group, g) => group.points.forEach(([px, py], p) => {
      const d = Math.hypot(px - x, py - y);
      if (d < 15 && (!nearest || d < nearest.d)) nearest = { g, p, d };
    }));
    if (nearest) edit((a) => a.groups[nearest.g].points.splice(nearest.p, 1));
    return;
  }
  const radius = Number(document.getElementById("radius").value);
  edit((a) => {
    if (!a.groups.length) newGroup(a);
    a.groups[Math.min(state.active, a.groups.length - 1)].points.push([x, y, radius]);
  });
});

document.getElementById("new-group").addEventListener("click", () => edit(newGroup));
for (const [id, weight] of [["relate-square", 0.6], ["relate-round", 0.3]]) {
  document.getElementById(id).addEventListener("click", () => {
    const ids = [...document.querySelectorAll("#groups li")]
      .filter((item) => item.querySelector(".pick").checked).map((item) => item.dataset.id);
    if (ids.length < 2) {
      say("Tick two groups or more first.", true);
      return;
    }
    edit((a) => a.relations.push({ ids, weight }));
  });
}
document.getElementById("undo").addEventListener("click", () => {
  if (!state.history.length) return;
  state.annotation = JSON.parse(state.history.pop());
  render();
});
document.getElementById("save").addEventListener("click", async () => {
  if (!opened()) return;
  // Groups without points are not saved (the format has no empty groups).
  const annotation = { ...state.annotation, groups: state.annotation.groups.filter((g) => g.points.length) };
  try {
    await api("/api/annotation", { root: state.root, name: state.name },
      { method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(annotation) });
    state.annotation = annotation;
    state.saved = snapshot();
    render();
    showStatus(`: written to data/${state.name}/`);
    canvas.dataset.saved = String(Number(canvas.dataset.saved || 0) + 1);
    listImages();
  } catch (error) {
    say(error.message, true);
  }
});

async function openImage(image) {
  if (image.name !== state.name && unsaved()
    && !confirm(`${state.name} has points that are not saved. Open ${image.name} and lose them?`)) return;
  try {
    const saved = await (await api("/api/annotation", { root: state.root, name: image.name })).json();
    state.image = await bitmap(await api("/api/photo", { root: state.root, path: saved.path }));
    state.name = image.name;
    state.annotation = { groups: saved.groups, relations: saved.relations };
    state.labels = saved.labels ?? {};
    state.saved = snapshot();
    state.history = [];
    state.active = 0;
    canvas.width = state.image.width;
    canvas.height = state.image.height;
    canvas.dataset.image = image.name;
    for (const item of document.getElementById("images").children) {
      item.classList.toggle("open", item.dataset.name === image.name);
    }
    render();
  } catch (error) {
    say(error.message, true);
  }
}

async function listImages() {
  const { benches } = await (await api("/api/benches")).json();
  const bench = benches.find((b) => b.root === state.root);
  document.getElementById("images").replaceChildren(...bench.images.map((image) => {
    const item = document.createElement("li");
    item.textContent = `${image.name}` + (image.groups ? ` (${image.groups} groups)` : "");
    item.dataset.name = image.name;
    item.classList.toggle("open", image.name === state.name);
    item.addEventListener("click", () => openImage(image));
    return item;
  }));
  return bench;
}

const select = document.getElementById("bench");
const { benches } = await (await api("/api/benches")).json();
if (!benches.length) {
  say("No benchmark: start the server with --bench FOLDER (a folder with an images/ folder).", true);
}
listFolders(select, benches);
async function openBench(root) {
  if (unsaved() && !confirm(`${state.name} has points that are not saved. Open ${root} and lose them?`)) {
    select.value = state.root;
    return;
  }
  Object.assign(state, { root, name: null, image: null, annotation: null });
  const bench = await listImages();
  if (bench.images.length) openImage(bench.images[0]);
}
select.addEventListener("change", () => openBench(select.value));
if (benches.length) openBench(benches[0].root);
