// The video page: open a video (listed, uploaded, or named in the address
// as ?root=R&path=P), pick a frame with the slider, click the materials to
// follow (each click one, in its colour; an alt- or right-click a
// material none of them may take; a click on a mark removes it; Ctrl+Z,
// Ctrl+Shift+Z or Ctrl+Y, and Esc undo, redo and clear), and Track: the
// server follows them through every frame (`matseg track`). Then the slider and Play scrub through the
// tracked frames with each material tinted in its colour; the label PNGs
// (a tar), the overlay video and one frame's labels (the raw label PNG,
// or a picture of them in the materials' colours) can be downloaded.

import { api, apiUrl, readPixels, bitmap, download, pngOf, takeFiles, uploadFile, say, PALETTE,
  colourTable, Layer, paintByRed, Clicks, bindEditKeys, takeClicks, drawClick, markerRadius } from "/common.js";

const canvas = document.getElementById("canvas");
const context = canvas.getContext("2d");
const slider = document.getElementById("frame");
const opacity = document.getElementById("opacity");
const list = document.getElementById("videos");
const pointList = document.getElementById("points");
const buttons = Object.fromEntries(["play", "track", "cancel", "save-labels", "save-overlay", "save-frame",
  "save-frame-colours"].map((id) => [id, document.getElementById(id)]));
// The downloads of a finished track.
const TRACK_BUTTONS = ["play", "save-labels", "save-overlay", "save-frame", "save-frame-colours"];
// job: the finished tracking job whose frames are shown (null: the video's
// own frames, points being picked); labels: the shown frame's labels.
const clicks = new Clicks(() => {
  listPoints();
  draw();
});
// A negative click's mark on a video: black, apart from the materials'
// colours.
const NEGATIVE_FILL = [20, 20, 20];
// Each label's colour: none for 0, material k's for k + 1.
const LABEL_COLOURS = colourTable((v) => (v ? [...PALETTE[(v - 1) % PALETTE.length], 1] : [0, 0, 0, 0]));
// labels: the shown frame's label PNG's pixels (label in red), drawn
// as `layer`.
const layer = new Layer();
const state = { video: null, name: "", info: null, clicked: 0, job: null,
  image: null, labels: null, shown: -1, playing: false, asked: 0 };

function draw() {
  if (!state.image) return;
  context.drawImage(state.image, 0, 0, canvas.width, canvas.height);
  if (state.labels) layer.drawOver(context, Number(opacity.value));
  if (state.shown === state.clicked) {
    const radius = markerRadius(canvas);
    let material = 0;
    for (const click of clicks.list) {
      const fill = click.positive ? PALETTE[material++ % PALETTE.length] : NEGATIVE_FILL;
      drawClick(context, click, radius, fill);
    }
  }
}

function listPoints() {
  let material = 0;
  pointList.replaceChildren(...clicks.list.map(({ x, y, positive }) => {
    const item = document.createElement("li");
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    const fill = positive ? PALETTE[material++ % PALETTE.length] : NEGATIVE_FILL;
    swatch.style.background = `rgb(${fill.join(",")})`;
    item.append(swatch, ` ${positive ? "" : "not: "}${x}, ${y} on frame ${state.clicked}`);
    return item;
  }));
  buttons.track.disabled = !clicks.count(true);
  document.getElementById("undo").disabled = !clicks.done.length;
  document.getElementById("redo").disabled = !clicks.undone.length;
}

// Shows frame `n`: the job's frame and labels once tracked, else the
// video's own frame. Only the newest request is drawn.
async function show(n) {
  const asked = ++state.asked;
  document.getElementById("frame-value").textContent = String(n);
  try {
    let image, labels = null;
    if (state.job) {
      [image, labels] = await Promise.all([
        api("/api/track/frame", { job: state.job, frame: n }).then(bitmap),
        api("/api/track/frame", { job: state.job, frame: n, part: "labels" }).then(readPixels),
      ]);
    } else {
      image = await bitmap(await api("/api/video/frame", { ...state.video, frame: n }));
    }
    if (asked !== state.asked) return;
    state.image = image;
    state.labels = labels;
    if (labels) {
      paintByRed(labels.bytes, layer.words(labels.width, labels.height), LABEL_COLOURS);
      layer.put();
    }
    state.shown = n;
    draw();
    canvas.dataset.frame = String(n);
  } catch (error) {
    say(error.message, true);
  }
}

async function open(video, name) {
  for (const item of list.children) item.classList.toggle("open", item.dataset.key === `${video.root}/${video.path}`);
  stop();
  Object.assign(state, { video, name: name.replace(/\.[^.]*$/, "").replace(/[^\w.-]+/g, "_"),
    clicked: 0, job: null, labels: null });
  clicks.forget();
  delete canvas.dataset.tracked;
  delete canvas.dataset.frame;
  for (const id of TRACK_BUTTONS) buttons[id].disabled = true;
  listPoints();
  try {
    state.info = await (await api("/api/video", video)).json();
  } catch (error) {
    say(error.message, true);
    return;
  }
  canvas.width = state.info.width;
  canvas.height = state.info.height;
  slider.max = String(Math.max(0, state.info.frames - 1));
  slider.value = "0";
  say(`${name}: ${state.info.width} x ${state.info.height}, ${state.info.frames} frames at ${state.info.fps.toFixed(2)} fps`);
  canvas.dataset.video = `${video.root}/${video.path}`;
  await show(0);
}

// Clicks pick materials on the shown frame. After a track they refine
// its clicks (on their frame) for the next track; on another frame, the
// first click starts a new choice there.
takeClicks(canvas, clicks, () => {
  if (!state.image || state.playing) return false;
  if (state.clicked !== state.shown) clicks.forget();
  if (state.job) {
    state.job = null;
    state.labels = null;
    delete canvas.dataset.tracked;
    for (const id of TRACK_BUTTONS) buttons[id].disabled = true;
  }
  state.clicked = state.shown;
  return true;
});
bindEditKeys(clicks);
document.getElementById("undo").addEventListener("click", () => clicks.undo());
document.getElementById("redo").addEventListener("click", () => clicks.redo());

slider.addEventListener("input", () => {
  const n = Number(slider.value);
  if (state.job) {
    show(n);
  } else {
    // The video's own frames are decoded from its start: shown when the
    // slider is let go.
    document.getElementById("frame-value").textContent = String(n);
  }
});
slider.addEventListener("change", () => {
  if (!state.job) show(Number(slider.value));
});
opacity.addEventListener("input", draw);
document.getElementById("clear").addEventListener("click", () => clicks.clear());

const sleep = (ms) => new Promise((done) => setTimeout(done, ms));

buttons.track.addEventListener("click", async () => {
  if (!clicks.count(true)) return;
  buttons.track.disabled = true;
  const started = performance.now();
  try {
    const asked = { ...state.video, frame: state.clicked, points: clicks.query(true), negative: clicks.query(false) };
    const { job } = await (await api("/api/track", asked, { method: "POST" })).json();
    buttons.cancel.hidden = false;
    buttons.cancel.onclick = () => api("/api/track", { job }, { method: "DELETE" }).catch(() => {});
    for (;;) {
      const answer = await (await api("/api/track", { job })).json();
      if (answer.state === "failed") throw new Error(answer.error);
      if (answer.state === "done") {
        state.report = answer.report;
        break;
      }
      say(`tracking: ${answer.done} of ${answer.total || "?"} frames`);
      await sleep(300);
    }
    state.job = job;
    const seconds = (performance.now() - started) / 1000;
    say(`${state.report.frames} frames tracked in ${seconds.toFixed(1)} s`);
    for (const id of TRACK_BUTTONS) buttons[id].disabled = false;
    slider.max = String(state.report.frames - 1);
    slider.value = String(state.clicked);
    await show(state.clicked);
    canvas.dataset.tracked = String(job);
  } catch (error) {
    say(error.message, true);
  }
  buttons.cancel.hidden = true;
  buttons.track.disabled = !clicks.count(true);
});

function stop() {
  state.playing = false;
  buttons.play.textContent = "Play";
}

// Plays the tracked frames at the video's rate (at most 30 a second),
// each frame shown before the next is asked for.
buttons.play.addEventListener("click", async () => {
  if (state.playing) return stop();
  state.playing = true;
  buttons.play.textContent = "Pause";
  const period = 1000 / Math.min(30, state.report.fps || 25);
  while (state.playing && state.job) {
    const started = performance.now();
    const next = (state.shown + 1) % state.report.frames;
    slider.value = String(next);
    await show(next);
    await sleep(Math.max(0, period - (performance.now() - started)));
  }
});

// The server names these downloads after the video.
buttons["save-labels"].addEventListener("click", () => {
  const link = document.createElement("a");
  link.href = apiUrl("/api/track/download", { job: state.job });
  link.click();
});
buttons["save-overlay"].addEventListener("click", () => {
  const link = document.createElement("a");
  link.href = apiUrl("/api/track/overlay", { job: state.job });
  link.click();
});
const frameName = () => `${state.name}-labels-${String(state.shown).padStart(6, "0")}`;
buttons["save-frame"].addEventListener("click", async () => {
  try {
    const labels = await api("/api/track/frame", { job: state.job, frame: state.shown, part: "labels" });
    download(await labels.blob(), `${frameName()}.png`);
  } catch (error) {
    say(error.message, true);
  }
});
// The shown frame's labels as a picture: each material in its colour,
// the pixels of none black.
const LABEL_PICTURE = colourTable((v) => (v ? [...PALETTE[(v - 1) % PALETTE.length], 1] : [0, 0, 0, 1]));
buttons["save-frame-colours"].addEventListener("click", async () => {
  const labels = state.labels;
  if (!labels) {
    say("Track the video first: the labels are the tracked frames'.", true);
    return;
  }
  const png = await pngOf(labels.width, labels.height, (words) => paintByRed(labels.bytes, words, LABEL_PICTURE));
  download(png, `${frameName()}-colours.png`);
});

// Uploads: the file picker and drops on the drop zone or the frame.
async function upload(file) {
  say(`uploading ${file.name}...`);
  try {
    const video = await uploadFile("/api/video/upload", file);
    await listVideos();
    await open({ root: video.root, path: video.path }, file.name);
  } catch (error) {
    say(error.message, true);
  }
}
takeFiles(document.getElementById("file"), [document.getElementById("drop"), canvas], upload);

async function listVideos() {
  const { videos } = await (await api("/api/videos")).json();
  list.replaceChildren(...videos.map((video) => {
    const item = document.createElement("li");
    item.textContent = `${video.root}: ${video.path}`;
    item.dataset.key = `${video.root}/${video.path}`;
    item.addEventListener("click", () => open(video, video.path));
    return item;
  }));
  return videos;
}

const videos = await listVideos();
const asked = new URLSearchParams(location.search);
if (asked.get("root") && asked.get("path")) {
  open({ root: asked.get("root"), path: asked.get("path") }, asked.get("path"));
} else if (videos.length) {
  open(videos[0], videos[0].path);
} else {
  say("No video in the served folders: upload one, or start the server with --data FOLDER.");
}
