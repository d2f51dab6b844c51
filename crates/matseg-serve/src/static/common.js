// What every page shares: the API helper (which carries the server's
// token, taken from the address the server printed and kept for the
// other pages), reading a PNG's pixels, the material palette (the same
// colours as the command line's overlays), drawing a similarity map over
// a photo, and downloads.

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

// A banner over the page when the server refuses it its API (no token, or
// another run's): what happened, and a field for the address the server
// printed, whose token is then kept.
function showAccessProblem(message) {
  let banner = document.getElementById("access");
  if (!banner) {
    banner = document.createElement("div");
    banner.id = "access";
    banner.setAttribute("role", "alert");
    banner.innerHTML = `<p></p><label>Address <code>matseg serve</code> printed:
      <input type="text" size="60" placeholder="http://127.0.0.1:8080/?token=..."></label>
      <button>Use it</button> <button hidden>Reload the page</button>`;
    const [field, use, reload] = [banner.querySelector("input"), ...banner.querySelectorAll("button")];
    use.addEventListener("click", async () => {
      const text = field.value.trim();
      const candidate = URL.canParse(text) ? new URL(text).searchParams.get("token") : text;
      if (await useToken(candidate)) {
        banner.querySelector("p").textContent = "Kept. Repeat what you were doing (Save again), or reload the page.";
        reload.hidden = false;
      } else {
        banner.querySelector("p").textContent = "That is not this server's address or token: copy the whole address it printed.";
      }
    });
    reload.addEventListener("click", () => location.reload());
    document.body.prepend(banner);
  }
  banner.querySelector("p").textContent = message;
}

const offered = new URLSearchParams(location.search).get("token");
if (offered && offered !== token && !(await useToken(offered))) {
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
// of its token shows the banner that says what to do, and never settles:
// the page waits there until the user gives the address, then repeats.
export async function api(path, params = {}, init = {}) {
  const headers = new Headers(init.headers);
  if (token) headers.set("x-matseg-token", token);
  if (init.method === "POST" && !headers.has("content-type")) headers.set("content-type", "application/json");
  const response = await fetch(apiUrl(path, params), { ...init, headers });
  if (!response.ok) {
    const body = await response.json().catch(() => ({ error: response.statusText }));
    if (response.status === 401) {
      showAccessProblem(body.error);
      return new Promise(() => {});
    }
    throw new Error(body.error);
  }
  return response;
}

// The RGBA pixels of an image response.
export async function pixels(response) {
  const bitmap = await createImageBitmap(await response.blob(),
    { colorSpaceConversion: "none", premultiplyAlpha: "none" });
  const scratch = new OffscreenCanvas(bitmap.width, bitmap.height).getContext("2d");
  scratch.drawImage(bitmap, 0, 0);
  return scratch.getImageData(0, 0, bitmap.width, bitmap.height).data;
}

// The similarities of a grey similarity PNG (`/api/similarity`), 0..1.
export async function similarities(response) {
  const grey = await pixels(response);
  return Float32Array.from({ length: grey.length / 4 }, (_, i) => grey[4 * i] / 255);
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

// Blends `colour(i)` = [r, g, b, a] over the canvas's pixels, `opacity`
// times; a = 0 leaves the photo.
export function blend(context, colour, opacity) {
  const { width, height } = context.canvas;
  const frame = context.getImageData(0, 0, width, height);
  for (let i = 0; i < width * height; i++) {
    const [r, g, b, a] = colour(i);
    const k = a * opacity;
    if (k <= 0) continue;
    frame.data[4 * i] = frame.data[4 * i] * (1 - k) + r * k;
    frame.data[4 * i + 1] = frame.data[4 * i + 1] * (1 - k) + g * k;
    frame.data[4 * i + 2] = frame.data[4 * i + 2] * (1 - k) + b * k;
  }
  context.putImageData(frame, 0, 0);
}

// A ring at (x, y) in `rgb`.
export function ring(context, x, y, rgb, radius = 6) {
  context.strokeStyle = `rgb(${rgb.join(",")})`;
  context.lineWidth = 2;
  context.beginPath();
  context.arc(x, y, radius, 0, 2 * Math.PI);
  context.stroke();
}

// The image pixel under a mouse event on a canvas drawn at any size.
export function pointOf(canvas, event) {
  const box = canvas.getBoundingClientRect();
  return [
    Math.min(canvas.width - 1, Math.max(0, Math.round((event.clientX - box.left) * canvas.width / box.width))),
    Math.min(canvas.height - 1, Math.max(0, Math.round((event.clientY - box.top) * canvas.height / box.height))),
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

// A PNG blob of grey values (one byte a pixel).
export async function greyPng(values, width, height) {
  const scratch = new OffscreenCanvas(width, height);
  const context = scratch.getContext("2d");
  const frame = context.createImageData(width, height);
  values.forEach((v, i) => {
    frame.data.set([v, v, v, 255], 4 * i);
  });
  context.putImageData(frame, 0, 0);
  return scratch.convertToBlob({ type: "image/png" });
}

// Sends a file's bytes to an upload route; its answer as JSON.
export async function uploadFile(path, file) {
  const init = { method: "POST", body: file, headers: { "content-type": "application/octet-stream" } };
  return (await api(path, { name: file.name }, init)).json();
}

// Calls `upload(file)` with the file picked in `input` or dropped on any
// of `zones`.
export function takeFiles(input, zones, upload) {
  input.addEventListener("change", (event) => {
    if (event.target.files.length) upload(event.target.files[0]);
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
// marker removes its click. `ready()`, called first, says whether clicks
// are taken (and may start a new choice).
export function takeClicks(canvas, clicks, ready = () => true) {
  const take = (event, positive) => {
    if (!ready()) return;
    const [x, y] = pointOf(canvas, event);
    const hit = clickIndexAt(clicks.list, [x, y], markerRadius(canvas));
    if (hit >= 0) clicks.remove(hit);
    else clicks.add({ x, y, positive });
  };
  canvas.addEventListener("click", (event) => take(event, !event.altKey));
  canvas.addEventListener("contextmenu", (event) => {
    event.preventDefault();
    take(event, false);
  });
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
// every direction (a square), in two passes of running distances.
export function dilate(mask, width, height, radius) {
  const pass = (input, count, length, at) => {
    const out = new Uint8Array(input.length);
    for (let line = 0; line < count; line++) {
      let since = Infinity;
      for (let k = 0; k < length; k++) {
        since = input[at(line, k)] ? 0 : since + 1;
        if (since <= radius) out[at(line, k)] = 1;
      }
      since = Infinity;
      for (let k = length - 1; k >= 0; k--) {
        since = input[at(line, k)] ? 0 : since + 1;
        if (since <= radius) out[at(line, k)] = 1;
      }
    }
    return out;
  };
  const rows = pass(mask, height, width, (y, x) => y * width + x);
  return pass(rows, width, height, (x, y) => y * width + x);
}

// The pixels on the edge of a region map (`region[i]`: a region's number,
// or -1 for none): those with a right or lower neighbour in another region.
export function edges(region, width, height) {
  const edge = new Uint8Array(width * height);
  for (let y = 0; y < height; y++) {
    for (let x = 0; x < width; x++) {
      const i = y * width + x;
      const r = region[i];
      if ((x + 1 < width && region[i + 1] !== r) || (y + 1 < height && region[i + width] !== r)) {
        edge[i] = 1;
      }
    }
  }
  return edge;
}

// Draws region edges over the canvas: a white line with a black border on
// each side, `unit` image pixels thick each (so they read at any size).
export function drawOutline(context, region, unit) {
  const { width, height } = context.canvas;
  const edge = edges(region, width, height);
  const white = dilate(edge, width, height, unit);
  const black = dilate(white, width, height, unit);
  const frame = context.getImageData(0, 0, width, height);
  for (let i = 0; i < width * height; i++) {
    if (!black[i]) continue;
    const v = white[i] ? 255 : 0;
    frame.data.set([v, v, v], 4 * i);
  }
  context.putImageData(frame, 0, 0);
}

// Greys the canvas: each pixel its lightness, darkened, so that a
// selection drawn over it in a bright colour reads on any photo.
export function greyOut(context) {
  const { width, height } = context.canvas;
  const frame = context.getImageData(0, 0, width, height);
  const d = frame.data;
  for (let i = 0; i < d.length; i += 4) {
    const v = 0.55 * (0.299 * d[i] + 0.587 * d[i + 1] + 0.114 * d[i + 2]);
    d[i] = d[i + 1] = d[i + 2] = v;
  }
  context.putImageData(frame, 0, 0);
}

// An opaque RGB PNG blob of `rgb(i)` = [r, g, b] for each pixel.
export async function rgbPng(rgb, width, height) {
  const scratch = new OffscreenCanvas(width, height);
  const context = scratch.getContext("2d");
  const frame = context.createImageData(width, height);
  for (let i = 0; i < width * height; i++) frame.data.set([...rgb(i), 255], 4 * i);
  context.putImageData(frame, 0, 0);
  return scratch.convertToBlob({ type: "image/png" });
}
