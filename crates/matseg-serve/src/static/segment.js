// The segment page: open a photo (listed, uploaded, or named in the
// address as ?root=R&path=P) and click a material: the server selects
// where else it is (its own decision, and a soft strength the threshold
// can cut). More clicks refine the selection: a click adds the material
// under it, an alt- or right-click leaves one out, a click on a mark
// removes it; Ctrl+Z, Ctrl+Shift+Z (or Ctrl+Y) and Esc undo, redo and
// clear. The selection is drawn as a tint, an outline, or in a bright
// colour over the photo greyed. "Segment automatically" splits the photo
// into K materials, each listed with its share and its mask. The server
// describes a photo once (started as soon as it is opened) and answers
// every click from its descriptors.

import { api, pixels, bitmap, blend, download, greyPng, rgbPng, takeFiles, uploadFile, COLOUR_MAPS, PALETTE,
  Clicks, bindEditKeys, takeClicks, drawClick, markerRadius, pixelsPerCss, setBusy, drawOutline, greyOut }
  from "/common.js";

// The solid tints to choose from: the one farthest from the photo's mean
// colour is used, so that a selection shows on red and orange photos too.
const SOLID_TINTS = [[255, 0, 0], [0, 255, 255], [255, 255, 0]];
const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d", { willReadFrequently: true });
const view = document.getElementById("view");
const status = document.getElementById("status");
const control = (id) => document.getElementById(id);
const [opacity, threshold, colours, mode, cut] = ["opacity", "threshold", "colours", "view-mode", "cut"].map(control);
const list = control("photos");
const legend = control("legend");
const clicks = new Clicks(update);
// layer: {kind: "selection", soft, mask} (the strength 0..1 and the
// method's own mask, 0 or 1, per pixel) or {kind: "auto", labels, k}.
// asked: the newest request (older answers are dropped); describing,
// waiting: what the busy mark says.
const state = { photo: null, name: "", image: null, layer: null, asked: 0, described: null,
  describing: false, waiting: false, solid: SOLID_TINTS[0] };

// The solid tint farthest from `image`'s mean colour.
function contrastingTint(image) {
  const small = document.createElement("canvas");
  small.width = small.height = 16;
  const c = small.getContext("2d");
  c.drawImage(image, 0, 0, 16, 16);
  const px = c.getImageData(0, 0, 16, 16).data;
  const mean = [0, 1, 2].map((k) => {
    let sum = 0;
    for (let i = k; i < px.length; i += 4) sum += px[i];
    return sum / (px.length / 4);
  });
  const distance = (t) => t.reduce((d, v, k) => d + (v - mean[k]) ** 2, 0);
  return SOLID_TINTS.reduce((best, t) => (distance(t) > distance(best) ? t : best));
}

// The tints of a selection: a strength 0..1 to [r, g, b, a].
const TINTS = { solid: () => [...state.solid, 1], ...COLOUR_MAPS };
// The colour of a selection over the greyed photo.
const ON_GREY = [0, 255, 255, 1];

// Each pixel's region: 0 selected, -1 not (a selection), or its material
// (automatic).
function regionsOf(layer) {
  if (layer.kind === "auto") return Int16Array.from(layer.labels);
  const cutAt = Number(threshold.value);
  const own = cut.value === "own";
  return Int16Array.from(layer.soft, (s, i) => ((own ? layer.mask[i] : s >= cutAt) ? 0 : -1));
}

function colourOf(layer, region, i) {
  if (layer.kind === "auto") return [...PALETTE[region[i] % PALETTE.length], 1];
  return mode.value === "grey" ? ON_GREY : TINTS[colours.value](layer.soft[i]);
}

function draw() {
  if (!state.image) return;
  context.drawImage(state.image, 0, 0);
  control("threshold-value").textContent = Number(threshold.value).toFixed(2);
  const layer = state.layer;
  if (layer) {
    const region = regionsOf(layer);
    if (mode.value === "outline") {
      drawOutline(context, region, Math.max(1, Math.round(pixelsPerCss(canvas))));
    } else {
      if (mode.value === "grey") greyOut(context);
      blend(context, (i) => (region[i] < 0 ? [0, 0, 0, 0] : colourOf(layer, region, i)), Number(opacity.value));
    }
    canvas.dataset.selected = String(region.reduce((n, r) => n + (r >= 0), 0));
  } else {
    delete canvas.dataset.selected;
  }
  const radius = markerRadius(canvas);
  for (const click of clicks.list) drawClick(context, click, radius);
  canvas.dataset.clicks = String(clicks.list.length);
}

// The busy mark: while the photo is described, and while the newest
// request is answered.
function showBusy() {
  const text = state.describing ? "describing the photo…" : state.waiting ? "selecting…" : "";
  setBusy(view, text);
}

// The selection layer of a selection PNG (red: strength; green: the mask).
async function selectionLayer(response) {
  const rgba = await pixels(response);
  const n = rgba.length / 4;
  const soft = new Float32Array(n);
  const mask = new Uint8Array(n);
  for (let i = 0; i < n; i++) {
    soft[i] = rgba[4 * i] / 255;
    mask[i] = rgba[4 * i + 1] > 127 ? 1 : 0;
  }
  return { kind: "selection", soft, mask };
}

// The automatic layer of a label PNG (red: the material's number).
async function autoLayer(response, k) {
  const rgba = await pixels(response);
  return { kind: "auto", k, labels: Uint8Array.from({ length: rgba.length / 4 }, (_, i) => rgba[4 * i]) };
}

function describeLayer() {
  const layer = state.layer;
  if (layer.kind === "auto") return `${layer.k} materials:`;
  const share = (100 * Number(canvas.dataset.selected)) / layer.soft.length;
  return `${clicks.count(true)} + ${clicks.count(false)} −: ${share.toFixed(1)}% of the photo selected,`;
}

// Asks for a layer (`call()`, once the photo is described) as request
// `asked`; only the newest request's answer is drawn.
async function request(asked, call) {
  const started = performance.now();
  state.waiting = true;
  showBusy();
  try {
    await state.described;
    const layer = await call();
    if (asked !== state.asked) return;
    state.layer = layer;
    draw();
    showLegend();
    status.textContent = `${describeLayer()} ${Math.round(performance.now() - started)} ms`;
    canvas.dataset.answered = String(Number(canvas.dataset.answered || 0) + 1);
  } catch (error) {
    if (asked === state.asked) status.textContent = error.message;
  } finally {
    if (asked === state.asked) {
      state.waiting = false;
      showBusy();
    }
  }
}

// The clicks changed: drawn at once, and the selection they make asked for.
function update() {
  control("undo").disabled = !clicks.done.length;
  control("redo").disabled = !clicks.undone.length;
  const asked = ++state.asked;
  state.waiting = false;
  showBusy();
  if (!clicks.count(true)) {
    state.layer = null;
    showLegend();
    status.textContent = clicks.list.length ? "A negative click needs a positive one: click the material to select." : "";
    draw();
    return;
  }
  draw();
  const params = { ...state.photo, positive: clicks.query(true), negative: clicks.query(false) };
  request(asked, async () => selectionLayer(await api("/api/select", params)));
}

// Describes the photo as soon as it is opened (the first answer takes a
// few seconds; the next ones milliseconds): a selection at its middle,
// whose answer is not shown.
function describe(photo) {
  state.describing = true;
  showBusy();
  const middle = `${Math.floor(canvas.width / 2)},${Math.floor(canvas.height / 2)}`;
  return api("/api/select", { ...photo, positive: middle })
    .then((response) => response.arrayBuffer())
    .catch(() => {})
    .finally(() => {
      if (state.photo !== photo) return;
      state.describing = false;
      showBusy();
      canvas.dataset.described = "1";
    });
}

async function open(photo, name) {
  for (const item of list.children) item.classList.toggle("open", item.dataset.key === `${photo.root}/${photo.path}`);
  state.asked++;
  Object.assign(state, { photo, image: null, layer: null, waiting: false, described: null,
    name: name.replace(/\.[^.]*$/, "").replace(/[^\w.-]+/g, "_") });
  clicks.forget();
  update();
  delete canvas.dataset.described;
  try {
    state.image = await bitmap(await api("/api/photo", photo));
    state.solid = contrastingTint(state.image);
  } catch (error) {
    status.textContent = error.message;
    return;
  }
  if (state.photo !== photo) return;
  canvas.width = state.image.width;
  canvas.height = state.image.height;
  status.textContent = `${name}: ${canvas.width} x ${canvas.height}`;
  canvas.dataset.photo = `${photo.root}/${photo.path}`;
  draw();
  state.described = describe(photo);
}

takeClicks(canvas, clicks, () => Boolean(state.image && state.photo));
bindEditKeys(clicks);
control("undo").addEventListener("click", () => clicks.undo());
control("redo").addEventListener("click", () => clicks.redo());
control("clear").addEventListener("click", () => clicks.clear());
for (const input of [opacity, colours, mode, cut]) input.addEventListener("input", draw);
threshold.addEventListener("input", () => {
  cut.value = "threshold";
  draw();
});
addEventListener("resize", draw);

control("auto").addEventListener("click", () => {
  if (!state.image) return;
  const k = Number(control("k").value);
  clicks.forget();
  update();
  request(state.asked, async () => autoLayer(await api("/api/auto", { ...state.photo, k }), k));
});

// The automatic segmentation's legend: each material's colour, its share
// of the photo, and its mask as a PNG.
function showLegend() {
  const layer = state.layer;
  legend.hidden = layer?.kind !== "auto";
  if (legend.hidden) return legend.replaceChildren();
  const counts = new Array(layer.k).fill(0);
  for (const l of layer.labels) counts[l]++;
  legend.replaceChildren(...counts.map((count, k) => {
    const item = document.createElement("li");
    item.innerHTML = `<span class="swatch"></span> <span></span> <button title="this material's mask">PNG</button>`;
    item.querySelector(".swatch").style.background = `rgb(${PALETTE[k % PALETTE.length].join(",")})`;
    item.children[1].textContent = `material ${k + 1}: ${((100 * count) / layer.labels.length).toFixed(1)}%`;
    item.querySelector("button").addEventListener("click", async () => {
      const bytes = Array.from(layer.labels, (l) => (l === k ? 255 : 0));
      download(await greyPng(bytes, canvas.width, canvas.height), `${state.name}-material-${k + 1}.png`);
    });
    return item;
  }));
}

// Downloads: the canvas as shown; the map (a selection's strength as
// grey, or the automatic materials in their colours); the mask (the
// selection shown, 255 in it); the selection as `selection.json`.
control("save-overlay").addEventListener("click", () => {
  canvas.toBlob((blob) => download(blob, `${state.name}-overlay.png`), "image/png");
});
control("save-map").addEventListener("click", async () => {
  const layer = state.layer;
  if (!layer) return;
  const { width, height } = canvas;
  if (layer.kind === "auto") {
    download(await rgbPng((i) => PALETTE[layer.labels[i] % PALETTE.length], width, height), `${state.name}-materials.png`);
  } else {
    download(await greyPng(Array.from(layer.soft, (s) => Math.round(s * 255)), width, height), `${state.name}-strength.png`);
  }
});
control("save-mask").addEventListener("click", async () => {
  const layer = state.layer;
  if (layer?.kind !== "selection") {
    status.textContent = "Click a material first (each automatic material's mask is in its legend).";
    return;
  }
  const region = regionsOf(layer);
  download(await greyPng(Array.from(region, (r) => (r >= 0 ? 255 : 0)), canvas.width, canvas.height), `${state.name}-mask.png`);
});
control("save-selection").addEventListener("click", async () => {
  if (!clicks.count(true)) {
    status.textContent = "Click a material first: the selection saved is its clicks' descriptors.";
    return;
  }
  try {
    const params = { ...state.photo, positive: clicks.query(true), negative: clicks.query(false) };
    download(await (await api("/api/select/save", params)).blob(), `${state.name}-selection.json`);
  } catch (error) {
    status.textContent = error.message;
  }
});

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
takeFiles(control("file"), [control("drop"), canvas], upload);

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
  control("more").hidden = listed >= page.total;
  return page;
}
control("more").addEventListener("click", listMore);

const first = await listMore();
const asked = new URLSearchParams(location.search);
if (asked.get("root") && asked.get("path")) {
  open({ root: asked.get("root"), path: asked.get("path") }, asked.get("path"));
} else if (first.photos.length) {
  open(first.photos[0], first.photos[0].path);
}
