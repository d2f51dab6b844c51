// What every page shares: the API helper (which carries the server's
// token, taken from the address the server printed and kept for the
// other pages), the status bar, reading a PNG's pixels, the material
// palette (the same colours as the command line's overlays), overlays
// drawn over a photo (each pixel's colour looked up in a table of 256,
// put on a layer of their own once and composited by the browser), and
// downloads.

export const TEMPERATURE = 0.2;
export const PALETTE = [
  [230, 25, 75], [60, 180, 75], [0, 130, 200], [255, 225, 25], [245, 130, 48],
  [145, 30, 180], [70, 240, 240], [240, 50, 230], [210, 245, 60], [250, 190, 212],
  [0, 128, 128], [220, 190, 255], [170, 110, 40], [255, 250, 200], [128, 0, 0],
  [170, 255, 195], [128, 128, 0], [255, 215, 180], [0, 0, 128], [128, 128, 128],
];

// The server's token, kept for this server's other pages (this browser
// keeps it apart from every other site's). The token in the page's
// address is kept only when the server accepts it, so that a link from
// another site cannot plant one.
const TOKEN_KEY = "matseg-token";
let token = localStorage.getItem(TOKEN_KEY);

// Whether the server accepts `candidate` as its token.
async function accepts(candidate) {
  const response = await fetch(`/api/status?${new URLSearchParams({ token: candidate })}`);
  return response.ok;
}

// Keeps `candidate` as the token when the server accepts it.
async function useToken(candidate) {
  if (!candidate || !(await accepts(candidate))) return false;
  token = candidate;
  localStorage.setItem(TOKEN_KEY, token);
  return true;
}

// Resolved when the banner's address gives a token the server accepts:
// the calls refused for want of it are then repeated.
let tokenGiven = null;
let giveToken = null;

// A banner over the page when the server refuses it its API (no token, or
// another run's): what happened, and a field for the address the server
// printed. Once the server accepts its token, the token is kept, the
// banner leaves and the refused calls are repeated: the page goes on.
function showAccessProblem(message) {
  let banner = document.getElementById("access");
  if (!banner) {
    banner = document.createElement("div");
    banner.id = "access";
    banner.setAttribute("role", "alert");
    banner.innerHTML = `<p></p><label>Address <code>matseg serve</code> printed:
      <input type="text" size="60" placeholder="http://127.0.0.1:8080/?token=..."></label>
      <button>Use it</button>`;
    const [field, use] = [banner.querySelector("input"), banner.querySelector("button")];
    const take = async () => {
      const text = field.value.trim();
      const candidate = URL.canParse(text) ? new URL(text).searchParams.get("token") : text;
      if (await useToken(candidate)) {
        banner.remove();
        giveToken?.();
        tokenGiven = giveToken = null;
      } else {
        banner.querySelector("p").textContent = "That is not this server's address or token: copy the whole address it printed.";
      }
    };
    use.addEventListener("click", take);
    field.addEventListener("keydown", (event) => {
      if (event.key === "Enter") take();
    });
    document.body.prepend(banner);
  }
  banner.querySelector("p").textContent = message;
}

// The token refused: the banner says so, and the promise settles when the
// user has given one the server accepts.
function waitForToken(message) {
  showAccessProblem(message);
  tokenGiven ??= new Promise((resolve) => {
    giveToken = resolve;
  });
  return tokenGiven;
}

// A token in the address is kept when the server accepts it; when it does
// not, a kept token that works is used instead (an old bookmark must not
// hide it), and only when there is none does the banner say so.
const offered = new URLSearchParams(location.search).get("token");
if (offered && offered !== token && !(await useToken(offered)) && !(token && (await accepts(token)))) {
  showAccessProblem("The token in this page's address is not this server's (the server makes a new one each time it starts).");
}

// The address of an API call, with the token when the server has one (for
// images and downloads, which cannot carry a header).
export function apiUrl(path, params = {}) {
  const query = new URLSearchParams(params);
  if (token) query.set("token", token);
  return `${path}?${query}`;
}

// Calls the API; a failed call throws the server's one-line error. A POST
// is typed: JSON unless the caller says otherwise (uploads send their
// bytes as application/octet-stream). A call the server refuses for want
// of its token shows the banner that says what to do, waits there until
// the user gives the address, and is then repeated: the page goes on.
export async function api(path, params = {}, init = {}) {
  const headers = new Headers(init.headers);
  if (token) headers.set("x-matseg-token", token);
  if (init.method === "POST" && !headers.has("content-type")) headers.set("content-type", "application/json");
  const response = await fetch(apiUrl(path, params), { ...init, headers });
  if (!response.ok) {
    const body = await response.json().catch(() => ({ error: response.statusText }));
    if (response.status === 401) {
      await waitForToken(body.error);
      return api(path, params, init);
    }
    throw new Error(body.error);
  }
  document.getElementById("access")?.remove();
  return response;
}

// Says `text` in the page's status bar (fixed at the bottom of the
// window, so always in sight); an error is marked as one.
export function say(text, error = false) {
  const status = document.getElementById("status");
  status.textContent = text;
  status.classList.toggle("error", error);
}

// The pixels of an image response: its size and its RGBA bytes, as
// stored (no colour conversion). The PNG is decoded off the page's thread.
export async function readPixels(response) {
  const bitmap = await createImageBitmap(await response.blob(),
    { colorSpaceConversion: "none", premultiplyAlpha: "none" });
  const { width, height } = bitmap;
  const scratch = new OffscreenCanvas(width, height).getContext("2d", { willReadFrequently: true });
  scratch.drawImage(bitmap, 0, 0);
  bitmap.close();
  return { width, height, bytes: scratch.getImageData(0, 0, width, height).data };
}

// An image response as a bitmap to draw.
export async function bitmap(response) {
  return createImageBitmap(await response.blob());
}

// The strength a similarity is drawn with: the training softmax's weight of
// the point's material relative to a perfect match, exp((s - 1) / T).
export function strength(similarity) {
  return Math.min(1, Math.exp((similarity - 1) / TEMPERATURE));
}

// Colour maps of a similarity in [0, 1]: colour and strength.
export const COLOUR_MAPS = {
  red: (s) => [255, 0, 0, strength(s)],
  heat: (s) => [Math.min(255, 3 * 255 * s), Math.max(0, Math.min(255, 3 * 255 * s - 255)),
    Math.max(0, 3 * 255 * s - 510), 1],
};

// The table of 256 colours an overlay's pixels are looked up in:
// `colour(v)` = [r, g, b, a] (a from 0 to 1) for each byte value v, as
// the 32-bit words of RGBA bytes (in the machine's byte order).
export function colourTable(colour) {
  const table = new Uint32Array(256);
  const bytes = new Uint8ClampedArray(table.buffer);
  for (let v = 0; v < 256; v++) {
    const [r, g, b, a] = colour(v);
    bytes.set([r, g, b, 255 * a], 4 * v);
  }
  return table;
}

// The palette's colours by label (label 0 too: the caller's table can
// start at any label).
export const PALETTE_TABLE = colourTable((v) => [...PALETTE[v % PALETTE.length], 1]);

// One RGBA word: the colour [r, g, b] with alpha a (0..1).
export function word(r, g, b, a = 1) {
  const one = new Uint32Array(1);
  new Uint8ClampedArray(one.buffer).set([r, g, b, 255 * a]);
  return one[0];
}

// An overlay: a layer of RGBA pixels the page fills (one 32-bit word a
// pixel, from a colour table), put on a canvas of its own once, and
// drawn over the photo with drawImage: the browser blends it (with the
// opacity as the global alpha) and scales it with the canvas.
export class Layer {
  constructor() {
    this.canvas = new OffscreenCanvas(1, 1);
    this.context = this.canvas.getContext("2d");
    this.frame = null;
  }

  // The layer's pixels at `width` x `height`, to fill (as left last time).
  words(width, height) {
    if (!this.frame || this.frame.width !== width || this.frame.height !== height) {
      this.frame = new ImageData(width, height);
      this.canvas.width = width;
      this.canvas.height = height;
    }
    return new Uint32Array(this.frame.data.buffer);
  }

  // The pixels filled: put on the layer's canvas.
  put() {
    this.context.putImageData(this.frame, 0, 0);
  }

  // Draws the layer over `context`'s canvas, `opacity` times.
  drawOver(context, opacity = 1) {
    context.save();
    context.globalAlpha = opacity;
    context.drawImage(this.canvas, 0, 0, context.canvas.width, context.canvas.height);
    context.restore();
  }
}

// Fills `words` with each pixel's colour looked up by its red byte in
// `table` (a map's value, a label): `bytes` are RGBA.
export function paintByRed(bytes, words, table) {
  for (let i = 0, j = 0; i < words.length; i++, j += 4) words[i] = table[bytes[j]];
}

// The photo greyed: each pixel its lightness, darkened, so that an
// overlay drawn over it in a bright colour reads on any photo.
export function greyCopy(image) {
  const { width, height } = image;
  const canvas = new OffscreenCanvas(width, height);
  const context = canvas.getContext("2d", { willReadFrequently: true });
  context.drawImage(image, 0, 0);
  const frame = context.getImageData(0, 0, width, height);
  const d = frame.data;
  for (let i = 0; i < d.length; i += 4) {
    const v = 0.55 * (0.299 * d[i] + 0.587 * d[i + 1] + 0.114 * d[i + 2]);
    d[i] = d[i + 1] = d[i + 2] = v;
  }
  context.putImageData(frame, 0, 0);
  return canvas;
}

// The solid tints to choose from: the one farthest from the photo's mean
// colour is used, so that an overlay shows on red and orange photos too.
const SOLID_TINTS = [[255, 0, 0], [0, 255, 255], [255, 255, 0]];

// The solid tint farthest from `image`'s mean colour.
export function contrastingTint(image) {
  const small = new OffscreenCanvas(16, 16).getContext("2d", { willReadFrequently: true });
  small.drawImage(image, 0, 0, 16, 16);
  const px = small.getImageData(0, 0, 16, 16).data;
  const mean = [0, 1, 2].map((k) => {
    let sum = 0;
    for (let i = k; i < px.length; i += 4) sum += px[i];
    return sum / (px.length / 4);
  });
  const distance = (t) => t.reduce((d, v, k) => d + (v - mean[k]) ** 2, 0);
  return SOLID_TINTS.reduce((best, t) => (distance(t) > distance(best) ? t : best));
}

// A ring at (x, y) in `rgb`.
export function ring(context, x, y, rgb, radius = 6) {
  context.strokeStyle = `rgb(${rgb.join(",")})`;
  context.lineWidth = 2;
  context.beginPath();
  context.arc(x, y, radius, 0, 2 * Math.PI);
  context.stroke();
}

// The image pixel under a pointer event on a canvas drawn at any size
// (the one the pointer's exact position lies in: pointer events carry
// fractions of a CSS pixel).
export function pointOf(canvas, event) {
  const box = canvas.getBoundingClientRect();
  return [
    Math.min(canvas.width - 1, Math.max(0, Math.floor((event.clientX - box.left) * canvas.width / box.width))),
    Math.min(canvas.height - 1, Math.max(0, Math.floor((event.clientY - box.top) * canvas.height / box.height))),
  ];
}

// Saves a blob as a file.
export function download(blob, name) {
  const link = document.createElement("a");
  link.href = URL.createObjectURL(blob);
  link.download = name;
  link.click();
  setTimeout(() => URL.revokeObjectURL(link.href), 1000);
}

// A PNG blob of grey values (`values`: one byte a pixel).
export async function greyPng(values, width, height) {
  const grey = colourTable((v) => [v, v, v, 1]);
  return pngOf(width, height, (words) => {
    for (let i = 0; i < words.length; i++) words[i] = grey[values[i]];
  });
}

// An opaque PNG blob of `width` x `height` pixels that `fill(words)`
// paints (one RGBA word a pixel).
export async function pngOf(width, height, fill) {
  const scratch = new OffscreenCanvas(width, height);
  const frame = new ImageData(width, height);
  fill(new Uint32Array(frame.data.buffer));
  scratch.getContext("2d").putImageData(frame, 0, 0);
  return scratch.convertToBlob({ type: "image/png" });
}

// Sends a file's bytes to an upload route; its answer as JSON.
export async function uploadFile(path, file) {
  const init = { method: "POST", body: file, headers: { "content-type": "application/octet-stream" } };
  return (await api(path, { name: file.name }, init)).json();
}

// Calls `upload(file)` with the file picked in `input` or dropped on any
// of `zones`. The field is emptied once the file is handed over, so it
// never shows the name of a file the server refused (and the same file
// can be picked again).
export function takeFiles(input, zones, upload) {
  input.addEventListener("change", (event) => {
    const files = [...event.target.files];
    event.target.value = "";
    if (files.length) upload(files[0]);
  });
  for (const zone of zones) {
    zone.addEventListener("dragover", (event) => event.preventDefault());
    zone.addEventListener("drop", (event) => {
      event.preventDefault();
      if (event.dataTransfer.files.length) upload(event.dataTransfer.files[0]);
    });
  }
}

// Fills `select` with the server's folders of one kind (`root: folder`).
export function listFolders(select, folders) {
  for (const { root, folder } of folders) {
    const option = document.createElement("option");
    option.value = root;
    option.textContent = `${root}: ${folder}`;
    select.append(option);
  }
}

// Marks the page the user is on in the links between pages.
for (const link of document.querySelectorAll("nav a")) {
  link.classList.toggle("here", link.pathname === location.pathname);
}

// Clicks on a photo, positive ("this material") and negative ("not that
// one"), with their history: every change (add, remove, clear) can be
// undone and redone. `changed()` is called after each.
export class Clicks {
  constructor(changed) {
    this.list = [];
    this.done = [];
    this.undone = [];
    this.changed = changed;
  }

  // A new list of clicks, as one edit.
  set(list) {
    this.done.push(this.list);
    this.list = list;
    this.undone = [];
    this.changed();
  }

  add(click) { this.set([...this.list, click]); }
  remove(index) { this.set(this.list.filter((_, i) => i !== index)); }
  clear() { if (this.list.length) this.set([]); }

  undo() {
    if (!this.done.length) return;
    this.undone.push(this.list);
    this.list = this.done.pop();
    this.changed();
  }

  redo() {
    if (!this.undone.length) return;
    this.done.push(this.list);
    this.list = this.undone.pop();
    this.changed();
  }

  // No clicks and no history (another photo), without `changed()`.
  forget() {
    Object.assign(this, { list: [], done: [], undone: [] });
  }

  // The clicks of one kind as the API takes them, `x,y;x,y`.
  query(positive) {
    return this.list.filter((c) => c.positive === positive).map((c) => `${c.x},${c.y}`).join(";");
  }

  count(positive) {
    return this.list.filter((c) => c.positive === positive).length;
  }
}

// Ctrl+Z undoes, Ctrl+Shift+Z and Ctrl+Y redo, Esc clears the clicks
// (Cmd for Ctrl on a Mac); keys typed in a text field are left alone.
export function bindEditKeys(clicks) {
  document.addEventListener("keydown", (event) => {
    if (event.target.matches?.("input[type=text], input[type=number], textarea, select")) return;
    const control = event.ctrlKey || event.metaKey;
    const key = event.key.toLowerCase();
    if (control && key === "z" && !event.shiftKey) clicks.undo();
    else if (control && (key === "y" || (key === "z" && event.shiftKey))) clicks.redo();
    else if (event.key === "Escape" && !control) clicks.clear();
    else return;
    event.preventDefault();
  });
}

// Image pixels per CSS pixel of a canvas drawn at any size (at least 1
// for drawing marks that stay readable).
export function pixelsPerCss(canvas) {
  const box = canvas.getBoundingClientRect();
  return box.width ? Math.max(1, canvas.width / box.width) : 1;
}

// The radius of a click's marker, in image pixels.
export function markerRadius(canvas) {
  return 9 * pixelsPerCss(canvas);
}

// Draws a click: a green disc with a "+" (positive) or a red one with a
// "−" (negative), or one filled with `fill` ([r, g, b]) when given,
// edged in white and outlined in black so that it shows on any photo.
export function drawClick(context, click, radius, fill = null) {
  const unit = radius / 9;
  context.save();
  context.beginPath();
  context.arc(click.x + 0.5, click.y + 0.5, radius, 0, 2 * Math.PI);
  context.fillStyle = fill ? `rgb(${fill.join(",")})` : click.positive ? "rgb(20, 160, 60)" : "rgb(215, 30, 45)";
  context.fill();
  context.lineWidth = 4 * unit;
  context.strokeStyle = "rgb(0, 0, 0)";
  context.stroke();
  context.lineWidth = 2 * unit;
  context.strokeStyle = "rgb(255, 255, 255)";
  context.stroke();
  context.beginPath();
  const arm = radius * 0.55;
  context.moveTo(click.x + 0.5 - arm, click.y + 0.5);
  context.lineTo(click.x + 0.5 + arm, click.y + 0.5);
  if (click.positive) {
    context.moveTo(click.x + 0.5, click.y + 0.5 - arm);
    context.lineTo(click.x + 0.5, click.y + 0.5 + arm);
  }
  context.lineWidth = 2.5 * unit;
  context.stroke();
  context.restore();
}

// The index of the click whose marker covers image pixel `point`, or -1.
export function clickIndexAt(clicks, [x, y], radius) {
  let best = -1;
  let nearest = radius * radius;
  clicks.forEach((c, i) => {
    const d = (c.x - x) ** 2 + (c.y - y) ** 2;
    if (d <= nearest) [best, nearest] = [i, d];
  });
  return best;
}

// Points on `canvas`: a click adds a positive one, an alt-click or a
// right-click (its menu kept closed) a negative one, and a click on a
// marker removes its click. They are taken when the button goes down, so
// that the answer is on its way before it comes up. `ready()`, called
// first, says whether clicks are taken (and may start a new choice).
export function takeClicks(canvas, clicks, ready = () => true) {
  canvas.addEventListener("pointerdown", (event) => {
    // The primary button (a Mac's Ctrl-click is a right-click), or the
    // secondary one.
    if (event.button !== 0 && event.button !== 2) return;
    if (!ready()) return;
    const positive = event.button === 0 && !event.altKey && !event.ctrlKey;
    const [x, y] = pointOf(canvas, event);
    const hit = clickIndexAt(clicks.list, [x, y], markerRadius(canvas));
    if (hit >= 0) clicks.remove(hit);
    else clicks.add({ x, y, positive });
  });
  canvas.addEventListener("contextmenu", (event) => event.preventDefault());
}

// Shows or hides the busy mark over `view` (a spinner and `text`, the
// cursor a progress one).
export function setBusy(view, text) {
  view.classList.toggle("busy", Boolean(text));
  let note = view.querySelector(".busy-note");
  if (!note) {
    note = document.createElement("div");
    note.className = "busy-note";
    note.setAttribute("role", "status");
    note.innerHTML = '<span class="spinner"></span> <span class="busy-text"></span>';
    view.prepend(note);
  }
  note.hidden = !text;
  note.querySelector(".busy-text").textContent = text || "";
}

// `mask` (one byte a pixel, non-zero set) grown by `radius` pixels in
// every direction (a square), in two passes of running distances (along
// the rows, then down the columns, a row at a time).
export function dilate(mask, width, height, radius) {
  const rows = new Uint8Array(mask.length);
  for (let y = 0; y < height; y++) {
    const start = y * width;
    let since = radius + 1;
    for (let i = start; i < start + width; i++) {
      since = mask[i] ? 0 : since + 1;
      if (since <= radius) rows[i] = 1;
    }
    since = radius + 1;
    for (let i = start + width - 1; i >= start; i--) {
      since = mask[i] ? 0 : since + 1;
      if (since <= radius) rows[i] = 1;
    }
  }
  const out = new Uint8Array(mask.length);
  const since = new Int32Array(width);
  since.fill(radius + 1);
  for (let y = 0, i = 0; y < height; y++) {
    for (let x = 0; x < width; x++, i++) {
      since[x] = rows[i] ? 0 : since[x] + 1;
      if (since[x] <= radius) out[i] = 1;
    }
  }
  since.fill(radius + 1);
  for (let y = height - 1; y >= 0; y--) {
    for (let x = 0, i = y * width; x < width; x++, i++) {
      since[x] = rows[i] ? 0 : since[x] + 1;
      if (since[x] <= radius) out[i] = 1;
    }
  }
  return out;
}

// The pixels on the edge of a region map (`region[i]`: a region's number,
// one byte a pixel): those with a right or lower neighbour in another
// region.
export function edges(region, width, height) {
  const edge = new Uint8Array(width * height);
  for (let y = 0, i = 0; y < height; y++) {
    const last = y + 1 === height;
    for (let x = 0; x < width; x++, i++) {
      const r = region[i];
      if ((x + 1 < width && region[i + 1] !== r) || (!last && region[i + width] !== r)) edge[i] = 1;
    }
  }
  return edge;
}

const WHITE = word(255, 255, 255);
const BLACK = word(0, 0, 0);

// Fills `words` with the region edges of `region`: a white line with a
// black border on each side, `unit` image pixels thick each (so they read
// at any size), and nothing elsewhere.
export function paintOutline(region, width, height, unit, words) {
  const white = dilate(edges(region, width, height), width, height, unit);
  const black = dilate(white, width, height, unit);
  for (let i = 0; i < words.length; i++) words[i] = white[i] ? WHITE : black[i] ? BLACK : 0;
}
