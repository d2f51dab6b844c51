// The segment page: open a photo, click a point to see the similarity of
// every pixel to it (red, exp((cosine - 1) / 0.2) as the net was trained to
// read it), shift-click to add points and see the photo split by nearest
// point. Descriptors are computed once per photo by the server.

const TEMPERATURE = 0.2;
const PALETTE = [[230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48],
  [145, 30, 180], [70, 240, 240], [240, 50, 230], [210, 245, 60], [250, 190, 212]];

const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d");
const status = document.getElementById("status");
const opacity = document.getElementById("opacity");
const threshold = document.getElementById("threshold");
const state = { photo: null, image: null, points: [], layer: null };

async function api(path, params) {
  const response = await fetch(`${path}?${new URLSearchParams(params)}`);
  if (!response.ok) {
    const body = await response.json().catch(() => ({ error: response.statusText }));
    throw new Error(body.error);
  }
  return response;
}

async function pixels(response) {
  const bitmap = await createImageBitmap(await response.blob());
  const scratch = new OffscreenCanvas(bitmap.width, bitmap.height).getContext("2d");
  scratch.drawImage(bitmap, 0, 0);
  return scratch.getImageData(0, 0, bitmap.width, bitmap.height).data;
}

function draw() {
  if (!state.image) return;
  context.drawImage(state.image, 0, 0);
  if (state.layer) {
    const frame = context.getImageData(0, 0, canvas.width, canvas.height);
    const alpha = Number(opacity.value);
    const cut = Number(threshold.value);
    for (let i = 0; i < state.layer.values.length; i++) {
      const [r, g, b, a] = state.layer.colour(i, cut);
      const k = a * alpha;
      frame.data[4 * i] = frame.data[4 * i] * (1 - k) + r * k;
      frame.data[4 * i + 1] = frame.data[4 * i + 1] * (1 - k) + g * k;
      frame.data[4 * i + 2] = frame.data[4 * i + 2] * (1 - k) + b * k;
    }
    context.putImageData(frame, 0, 0);
  }
  for (const [i, [x, y]] of state.points.entries()) {
    const [r, g, b] = state.points.length > 1 ? PALETTE[i % PALETTE.length] : [255, 255, 255];
    context.strokeStyle = `rgb(${r},${g},${b})`;
    context.lineWidth = 2;
    context.beginPath();
    context.arc(x, y, 6, 0, 2 * Math.PI);
    context.stroke();
  }
}

async function update() {
  const params = { ...state.photo, points: state.points.map(([x, y]) => `${x},${y}`).join(";") };
  const started = performance.now();
  try {
    if (state.points.length === 1) {
      const grey = await pixels(await api("/api/similarity", params));
      const values = Array.from({ length: grey.length / 4 }, (_, i) => grey[4 * i] / 255);
      state.layer = {
        values,
        colour: (i, cut) => values[i] < cut ? [0, 0, 0, 0]
          : [255, 0, 0, Math.min(1, Math.exp((values[i] - 1) / TEMPERATURE))],
      };
    } else if (state.points.length > 1) {
      const labels = await pixels(await api("/api/segment", params));
      const values = Array.from({ length: labels.length / 4 }, (_, i) => labels[4 * i]);
      state.layer = { values, colour: (i) => [...PALETTE[values[i] % PALETTE.length], 1] };
    } else {
      state.layer = null;
    }
    status.textContent = state.points.length
      ? `${state.points.length} point(s): ${Math.round(performance.now() - started)} ms` : "";
  } catch (error) {
    status.textContent = error.message;
  }
  draw();
}

async function open(photo, item) {
  document.querySelectorAll("#photos li").forEach((li) => li.classList.toggle("open", li === item));
  state.photo = photo;
  state.points = [];
  state.layer = null;
  const response = await api("/api/photo", photo);
  state.image = await createImageBitmap(await response.blob());
  canvas.width = state.image.width;
  canvas.height = state.image.height;
  status.textContent = `${photo.path}: ${canvas.width} x ${canvas.height}`;
  draw();
}

canvas.addEventListener("click", (event) => {
  if (!state.image) return;
  const box = canvas.getBoundingClientRect();
  const x = Math.round((event.clientX - box.left) * canvas.width / box.width);
  const y = Math.round((event.clientY - box.top) * canvas.height / box.height);
  state.points = event.shiftKey ? [...state.points, [x, y]] : [[x, y]];
  update();
});
opacity.addEventListener("input", draw);
threshold.addEventListener("input", draw);
document.getElementById("clear").addEventListener("click", () => {
  state.points = [];
  update();
});

const listing = await (await api("/api/photos", { limit: 200 })).json();
const list = document.getElementById("photos");
for (const photo of listing.photos) {
  const item = document.createElement("li");
  item.textContent = `${photo.root}: ${photo.path}`;
  item.addEventListener("click", () => open(photo, item));
  list.append(item);
}
if (listing.photos.length) open(listing.photos[0], list.firstChild);
