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
//
// Drawing an answer: the PNG is decoded off the page's thread, each
// pixel's overlay colour looked up in a table of 256 (by its strength or
// its label) into a layer of its own, and the browser draws the photo
// and the layer over it onto the canvas. The view's controls redo the
// layer from the answer kept; the opacity and the clicks' marks only
// redraw the canvas.

import { api, readPixels, bitmap, download, greyPng, pngOf, takeFiles, uploadFile, say, COLOUR_MAPS,
  PALETTE, PALETTE_TABLE, colourTable, Layer, greyCopy, contrastingTint, paintOutline,
  Clicks, bindEditKeys, takeClicks, drawClick, markerRadius, pixelsPerCss, setBusy }
  from "/common.js";

const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d");
const view = document.getElementById("view");
const control = (id) => document.getElementById(id);
const [opacity, threshold, colours, mode, cut] = ["opacity", "threshold", "colours", "view-mode", "cut"].map(control);
const list = control("photos");
const legend = control("legend");
const clicks = new Clicks(update);
const layer = new Layer();
// answer: the server's answer drawn, {kind: "selection" | "auto", width,
// height, bytes (RGBA: a selection's strength in red and its own mask in
// green, or each pixel's material in red), k, ms (from the click to its
// picture)}; selected: the pixels in the selection shown (every pixel of
// an automatic split); shares: an automatic split's pixels by material.
// asked: the newest request (older answers are dropped); describing,
// waiting: what the busy mark says.
const state = { photo: null, name: "", image: null, grey: null, answer: null, selected: 0, shares: null,
  asked: 0, described: null, describing: false, waiting: false, solid: [255, 0, 0] };

// The colour of a selection over the greyed photo.
const ON_GREY = colourTable(() => [0, 255, 255, 1]);

// The table of a selection's colours by strength (0..255).
function selectionColours() {
  if (mode.value === "grey") return ON_GREY;
  if (colours.value === "solid") return colourTable(() => [...state.solid, 1]);
  const map = COLOUR_MAPS[colours.value];
  return colourTable((v) => map(v / 255));
}

// Which strengths (0..255) the threshold keeps.
function thresholdKeeps() {
  const cutAt = Number(threshold.value);
  return Uint8Array.from({ length: 256 }, (_, v) => v / 255 >= cutAt);
}

// Each pixel's region of the answer, one byte a pixel: 1 selected, 0 not
// (a selection), or its material (automatic).
function regionsOf(answer) {
  const { bytes } = answer;
  const region = new Uint8Array(answer.width * answer.height);
  if (answer.kind === "auto") {
    for (let i = 0, j = 0; i < region.length; i++, j += 4) region[i] = bytes[j];
  } else if (cut.value === "own") {
    for (let i = 0, j = 1; i < region.length; i++, j += 4) region[i] = bytes[j] > 127 ? 1 : 0;
  } else {
    const keeps = thresholdKeeps();
    for (let i = 0, j = 0; i < region.length; i++, j += 4) region[i] = keeps[bytes[j]];
  }
  return region;
}

// Redoes the layer from the answer and the view's controls, and redraws.
function render() {
  control("threshold-value").textContent = Number(threshold.value).toFixed(2);
  const answer = state.answer;
  if (answer) {
    const { width, height, bytes } = answer;
    const words = layer.words(width, height);
    const n = words.length;
    if (mode.value === "outline") {
      const region = regionsOf(answer);
      paintOutline(region, width, height, Math.max(1, Math.round(pixelsPerCss(canvas))), words);
      state.selected = answer.kind === "auto" ? n : region.reduce((sum, r) => sum + r, 0);
    } else if (answer.kind === "auto") {
      for (let i = 0, j = 0; i < n; i++, j += 4) words[i] = PALETTE_TABLE[bytes[j]];
      state.selected = n;
    } else {
      // The selection's pixels in their colours, the others clear; the
      // method's own mask (green), or the strength (red) cut.
      const table = selectionColours();
      let selected = 0;
      if (cut.value === "own") {
        for (let i = 0, j = 0; i < n; i++, j += 4) {
          if (bytes[j + 1] > 127) {
            words[i] = table[bytes[j]];
            selected++;
          } else {
            words[i] = 0;
          }
        }
      } else {
        const keeps = thresholdKeeps();
        for (let i = 0, j = 0; i < n; i++, j += 4) {
          const s = bytes[j];
          if (keeps[s]) {
            words[i] = table[s];
            selected++;
          } else {
            words[i] = 0;
          }
        }
      }
      state.selected = selected;
    }
    layer.put();
  }
  draw();
  showStatus();
}

// Draws the canvas: the photo (greyed in that view), the answer's layer
// over it, the clicks' marks.
function draw() {
  if (!state.image) return;
  const answer = state.answer;
  const grey = answer && mode.value === "grey";
  if (grey && !state.grey) state.grey = greyCopy(state.image);
  context.drawImage(grey ? state.grey : state.image, 0, 0);
  if (answer) {
    layer.drawOver(context, mode.value === "outline" ? 1 : Number(opacity.value));
    canvas.dataset.selected = String(state.selected);
  } else {
    delete canvas.dataset.selected;
  }
  const radius = markerRadius(canvas);
  for (const click of clicks.list) drawClick(context, click, radius);
  canvas.dataset.clicks = String(clicks.list.length);
}

// The status: the answer shown (the clicks, the share of the photo its
// selection takes as now cut, the time from the click to its picture).
function showStatus() {
  const answer = state.answer;
  if (!answer) return;
  if (answer.kind === "auto") {
    say(`${answer.k} materials: ${answer.ms} ms`);
  } else {
    const share = (100 * state.selected) / (answer.width * answer.height);
    say(`${clicks.count(true)} + ${clicks.count(false)} −: ${share.toFixed(1)}% of the photo selected, ${answer.ms} ms`);
  }
}

// The busy mark: while the photo is described, and while the newest
// request is answered.
function showBusy() {
  const text = state.describing ? "describing the photo…" : state.waiting ? "selecting…" : "";
  setBusy(view, text);
}

// Asks for an answer (`call()`, once the photo is described) as request
// `asked`, from a click at `started`; only the newest request's answer
// is drawn.
async function request(asked, started, call) {
  state.waiting = true;
  showBusy();
  try {
    await state.described;
    const answer = await call();
    if (asked !== state.asked) return;
    if (answer.width !== canvas.width || answer.height !== canvas.height) {
      throw new Error(`the answer is ${answer.width} x ${answer.height}, the photo ${canvas.width} x ${canvas.height}`);
    }
    answer.ms = Math.round(performance.now() - started);
    state.answer = answer;
    render();
    showLegend();
    canvas.dataset.answered = String(Number(canvas.dataset.answered || 0) + 1);
  } catch (error) {
    if (asked === state.asked) say(error.message, true);
  } finally {
    if (asked === state.asked) {
      state.waiting = false;
      showBusy();
    }
  }
}

// The clicks changed: their marks drawn at once (over the answer shown
// until the new one comes), and the selection they make asked for.
function update() {
  const started = performance.now();
  control("undo").disabled = !clicks.done.length;
  control("redo").disabled = !clicks.undone.length;
  const asked = ++state.asked;
  state.waiting = false;
  showBusy();
  if (!clicks.count(true)) {
    state.answer = null;
    showLegend();
    say(clicks.list.length ? "A negative click needs a positive one: click the material to select." : "",
      clicks.list.length > 0);
    draw();
    return;
  }
  draw();
  const params = { ...state.photo, positive: clicks.query(true), negative: clicks.query(false) };
  request(asked, started, async () => ({ kind: "selection", ...(await readPixels(await api("/api/select", params))) }));
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
  Object.assign(state, { photo, image: null, grey: null, answer: null, waiting: false, described: null,
    name: name.replace(/\.[^.]*$/, "").replace(/[^\w.-]+/g, "_") });
  clicks.forget();
  update();
  delete canvas.dataset.described;
  try {
    state.image = await bitmap(await api("/api/photo", photo));
    state.solid = contrastingTint(state.image);
  } catch (error) {
    say(error.message, true);
    return;
  }
  if (state.photo !== photo) return;
  canvas.width = state.image.width;
  canvas.height = state.image.height;
  say(`${name}: ${canvas.width} x ${canvas.height}`);
  canvas.dataset.photo = `${photo.root}/${photo.path}`;
  draw();
  state.described = describe(photo);
}

takeClicks(canvas, clicks, () => Boolean(state.image && state.photo));
bindEditKeys(clicks);
control("undo").addEventListener("click", () => clicks.undo());
control("redo").addEventListener("click", () => clicks.redo());
control("clear").addEventListener("click", () => clicks.clear());
for (const input of [colours, mode, cut]) input.addEventListener("input", render);
opacity.addEventListener("input", draw);
threshold.addEventListener("input", () => {
  cut.value = "threshold";
  render();
});
// The outline's width and the marks' size follow the photo's size on
// the screen.
addEventListener("resize", () => (mode.value === "outline" ? render() : draw()));

control("auto").addEventListener("click", () => {
  if (!state.image) return;
  const started = performance.now();
  const k = Number(control("k").value);
  clicks.forget();
  update();
  request(state.asked, started, async () =>
    ({ kind: "auto", k, ...(await readPixels(await api("/api/auto", { ...state.photo, k }))) }));
});

// The automatic segmentation's legend: each material's colour, its share
// of the photo, and its mask as a PNG.
function showLegend() {
  const answer = state.answer;
  legend.hidden = answer?.kind !== "auto";
  if (legend.hidden) return legend.replaceChildren();
  const counts = new Array(answer.k).fill(0);
  const { bytes } = answer;
  for (let j = 0; j < bytes.length; j += 4) counts[bytes[j]]++;
  const pixels = answer.width * answer.height;
  legend.replaceChildren(...counts.map((count, k) => {
    const item = document.createElement("li");
    item.innerHTML = `<span class="swatch"></span> <span></span> <button title="this material's mask">PNG</button>`;
    item.querySelector(".swatch").style.background = `rgb(${PALETTE[k % PALETTE.length].join(",")})`;
    item.children[1].textContent = `material ${k + 1}: ${((100 * count) / pixels).toFixed(1)}%`;
    item.querySelector("button").addEventListener("click", async () => {
      const mask = Uint8Array.from(regionsOf(answer), (l) => (l === k ? 255 : 0));
      download(await greyPng(mask, answer.width, answer.height), `${state.name}-material-${k + 1}.png`);
    });
    return item;
  }));
}

// Downloads: the canvas as shown; the map (a selection's strength as
// grey, or the automatic materials in their colours); the mask (the
// selection shown, 255 in it); the selection as `selection.json`.
control("save-overlay").addEventListener("click", () => {
  if (!state.image) {
    say("Open a photo first.", true);
    return;
  }
  canvas.toBlob((blob) => download(blob, `${state.name}-overlay.png`), "image/png");
});
control("save-map").addEventListener("click", async () => {
  const answer = state.answer;
  if (!answer) {
    say("No map yet: click a material (its strength is the map), or segment automatically (its materials).", true);
    return;
  }
  const { width, height, bytes } = answer;
  if (answer.kind === "auto") {
    const png = await pngOf(width, height, (words) => {
      for (let i = 0, j = 0; i < words.length; i++, j += 4) words[i] = PALETTE_TABLE[bytes[j]];
    });
    download(png, `${state.name}-materials.png`);
  } else {
    const strength = new Uint8Array(width * height);
    for (let i = 0, j = 0; i < strength.length; i++, j += 4) strength[i] = bytes[j];
    download(await greyPng(strength, width, height), `${state.name}-strength.png`);
  }
});
control("save-mask").addEventListener("click", async () => {
  const answer = state.answer;
  if (answer?.kind !== "selection") {
    say("Click a material first (each automatic material's mask is in its legend).", true);
    return;
  }
  const mask = Uint8Array.from(regionsOf(answer), (r) => (r ? 255 : 0));
  download(await greyPng(mask, answer.width, answer.height), `${state.name}-mask.png`);
});
control("save-selection").addEventListener("click", async () => {
  if (!clicks.count(true)) {
    say("Click a material first: the selection saved is its clicks' descriptors.", true);
    return;
  }
  try {
    const params = { ...state.photo, positive: clicks.query(true), negative: clicks.query(false) };
    download(await (await api("/api/select/save", params)).blob(), `${state.name}-selection.json`);
  } catch (error) {
    say(error.message, true);
  }
});

// Uploads: the file picker and drops on the drop zone or the photo.
async function upload(file) {
  say(`uploading ${file.name}...`);
  try {
    const photo = await uploadFile("/api/upload", file);
    list.prepend(listItem({ root: photo.root, path: photo.path }, `uploaded: ${file.name}`, file.name));
    await open({ root: photo.root, path: photo.path }, file.name);
  } catch (error) {
    say(error.message, true);
  }
}
takeFiles(control("file"), [control("drop"), canvas], upload);

// A photo's entry in the list, shown as `label`: a click opens it under
// `name` (what downloads are named after).
function listItem(photo, label, name = photo.path) {
  const item = document.createElement("li");
  item.textContent = label;
  item.dataset.key = `${photo.root}/${photo.path}`;
  item.addEventListener("click", () => open(photo, name));
  return item;
}

// The photo list, a page at a time.
let listed = 0;
async function listMore() {
  const page = await (await api("/api/photos", { offset: listed, limit: 200 })).json();
  for (const photo of page.photos) list.append(listItem(photo, `${photo.root}: ${photo.path}`));
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
} else {
  say("No photo to list: drop one here, or start the server with --data FOLDER.");
}
