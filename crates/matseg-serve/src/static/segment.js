// The segment page: open a photo (listed, uploaded, or named in the
// address as ?root=R&path=P), click a point to see the similarity of every
// pixel to it, shift-click to add points and see the photo split among
// them (pixels below the threshold in none), or split it automatically
// into K materials. The server describes a photo once and answers every
// click from its descriptors.

import { api, pixels, similarities, bitmap, blend, ring, pointOf, download, greyPng, takeFiles, uploadFile, COLOUR_MAPS, PALETTE }
  from "/common.js";

const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d", { willReadFrequently: true });
const status = document.getElementById("status");
const opacity = document.getElementById("opacity");
const threshold = document.getElementById("threshold");
const colours = document.getElementById("colours");
const list = document.getElementById("photos");
// layer: {kind: "similarity", values} (cosine in 0..1) or
// {kind: "labels", labels, values} (label and its cosine, or 1 for clusters).
const state = { photo: null, name: "", image: null, points: [], layer: null };

function draw() {
  if (!state.image) return;
  context.drawImage(state.image, 0, 0);
  const layer = state.layer;
  const cut = Number(threshold.value);
  document.getElementById("threshold-value").textContent = cut.toFixed(2);
  if (layer?.kind === "similarity") {
    const colour = COLOUR_MAPS[colours.value];
    blend(context, (i) => layer.values[i] < cut ? [0, 0, 0, 0] : colour(layer.values[i]), Number(opacity.value));
  } else if (layer?.kind === "labels") {
    blend(context, (i) => layer.values[i] < cut ? [0, 0, 0, 0]
      : [...PALETTE[layer.labels[i] % PALETTE.length], 1], Number(opacity.value));
  }
  for (const [i, [x, y]] of state.points.entries()) {
    ring(context, x, y, state.points.length > 1 ? PALETTE[i % PALETTE.length] : [255, 255, 255]);
  }
}

// The label layer of an RGB label PNG (red: label; green: its strength).
async function labelLayer(response) {
  const rgba = await pixels(response);
  const n = rgba.length / 4;
  const labels = new Uint8Array(n);
  const values = new Float32Array(n);
  for (let i = 0; i < n; i++) {
    labels[i] = rgba[4 * i];
    values[i] = rgba[4 * i + 1] / 255;
  }
  return { kind: "labels", labels, values };
}

async function answer(started, request) {
  try {
    state.layer = await request();
    status.textContent = `${state.layer ? describeLayer() : ""} ${Math.round(performance.now() - started)} ms`;
    canvas.dataset.answered = String(Number(canvas.dataset.answered || 0) + 1);
  } catch (error) {
    status.textContent = error.message;
  }
  draw();
}

function describeLayer() {
  if (state.layer.kind === "similarity") return "1 point:";
  return state.points.length ? `${state.points.length} points:` : `${state.layer.k} materials:`;
}

function update() {
  const params = { ...state.photo, points: state.points.map(([x, y]) => `${x},${y}`).join(";") };
  answer(performance.now(), async () => {
    if (state.points.length === 1) {
      return { kind: "similarity", values: await similarities(await api("/api/similarity", params)) };
    }
    if (state.points.length > 1) return labelLayer(await api("/api/segment", params));
    return null;
  });
}

async function open(photo, name) {
  for (const item of list.children) item.classList.toggle("open", item.dataset.key === `${photo.root}/${photo.path}`);
  state.photo = photo;
  state.name = name.replace(/\.[^.]*$/, "").replace(/[^\w.-]+/g, "_");
  state.points = [];
  state.layer = null;
  try {
    state.image = await bitmap(await api("/api/photo", photo));
  } catch (error) {
    status.textContent = error.message;
    return;
  }
  canvas.width = state.image.width;
  canvas.height = state.image.height;
  status.textContent = `${name}: ${canvas.width} x ${canvas.height}`;
  canvas.dataset.photo = `${photo.root}/${photo.path}`;
  draw();
}

canvas.addEventListener("click", (event) => {
  if (!state.image) return;
  const point = pointOf(canvas, event);
  state.points = event.shiftKey ? [...state.points, point] : [point];
  update();
});
for (const control of [opacity, threshold, colours]) control.addEventListener("input", draw);
document.getElementById("clear").addEventListener("click", () => {
  state.points = [];
  update();
});
document.getElementById("auto").addEventListener("click", () => {
  if (!state.image) return;
  const k = Number(document.getElementById("k").value);
  state.points = [];
  answer(performance.now(), async () => ({ ...await labelLayer(await api("/api/auto", { ...state.photo, k })), k }));
});

// Downloads: the canvas as shown, the map (grey similarity, or labels with
// 0 for none and label + 1 elsewhere) and the mask (the pixels at or above
// the threshold, or of the first label).
document.getElementById("save-overlay").addEventListener("click", () => {
  canvas.toBlob((blob) => download(blob, `${state.name}-overlay.png`), "image/png");
});
function layerBytes(mask) {
  const layer = state.layer;
  const cut = Number(threshold.value);
  if (layer.kind === "similarity") {
    return Array.from(layer.values, (v) => mask ? (v >= cut ? 255 : 0) : Math.round(v * 255));
  }
  return Array.from(layer.labels, (l, i) => layer.values[i] < cut ? 0 : mask ? (l === 0 ? 255 : 0) : l + 1);
}
for (const [id, mask] of [["save-map", false], ["save-mask", true]]) {
  document.getElementById(id).addEventListener("click", async () => {
    if (!state.layer) return;
    const kind = state.layer.kind === "similarity" ? (mask ? "mask" : "similarity") : (mask ? "mask" : "labels");
    download(await greyPng(layerBytes(mask), canvas.width, canvas.height), `${state.name}-${kind}.png`);
  });
}

// Uploads: the file picker and drops on the drop zone or the photo.
async function upload(file) {
  status.textContent = `uploading ${file.name}...`;
  try {
    const photo = await uploadFile("/api/upload", file);
    await open({ root: photo.root, path: photo.path }, file.name);
  } catch (error) {
    status.textContent = error.message;
  }
}
takeFiles(document.getElementById("file"), [document.getElementById("drop"), canvas], upload);

// The photo list, a page at a time.
let listed = 0;
async function listMore() {
  const page = await (await api("/api/photos", { offset: listed, limit: 200 })).json();
  for (const photo of page.photos) {
    const item = document.createElement("li");
    item.textContent = `${photo.root}: ${photo.path}`;
    item.dataset.key = `${photo.root}/${photo.path}`;
    item.addEventListener("click", () => open(photo, photo.path));
    list.append(item);
  }
  listed += page.photos.length;
  document.getElementById("more").hidden = listed >= page.total;
  return page;
}
document.getElementById("more").addEventListener("click", listMore);

const first = await listMore();
const asked = new URLSearchParams(location.search);
if (asked.get("root") && asked.get("path")) {
  open({ root: asked.get("root"), path: asked.get("path") }, asked.get("path"));
} else if (first.photos.length) {
  open(first.photos[0], first.photos[0].path);
}
