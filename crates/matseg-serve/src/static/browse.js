// The browse page: a dataset folder given to `matseg serve --data` (MatSeg
// sample folders or WebDataset shards), a page of thumbnails at a time;
// one sample shows its image, the annotation over it, each material's soft
// mask, the ROI and the sidecar (sources, licences, recipe values).

import { api, apiUrl, say, PALETTE, listFolders } from "/common.js";

const PAGE = 48;
const select = document.getElementById("dataset");
const grid = document.getElementById("grid");
const detail = document.getElementById("sample");
const state = { root: null, total: 0, offset: 0 };

function figure(src, caption, colour) {
  const box = document.createElement("figure");
  const image = document.createElement("img");
  image.src = src;
  image.alt = caption;
  const text = document.createElement("figcaption");
  text.textContent = caption;
  if (colour) text.style.borderLeft = `1em solid rgb(${colour.join(",")})`;
  box.append(image, text);
  return box;
}

async function showPage(offset) {
  state.offset = Math.max(0, Math.min(offset, Math.max(0, state.total - 1)));
  state.offset -= state.offset % PAGE;
  detail.hidden = true;
  grid.hidden = false;
  grid.replaceChildren();
  try {
    const page = await (await api("/api/samples", { root: state.root, offset: state.offset, limit: PAGE })).json();
    state.total = page.total;
    for (const sample of page.samples) {
      const tile = figure(apiUrl("/api/sample/image", { root: state.root, index: sample.index, part: "thumbnail" }),
        `${sample.index}: ${sample.key}`);
      tile.classList.add("tile");
      tile.dataset.index = sample.index;
      tile.addEventListener("click", () => showSample(sample.index));
      grid.append(tile);
    }
    say(`samples ${state.offset}-${state.offset + page.samples.length - 1} of ${page.total}`);
  } catch (error) {
    say(error.message, true);
  }
}

async function showSample(index) {
  try {
    const sample = await (await api("/api/sample", { root: state.root, index })).json();
    grid.hidden = true;
    detail.hidden = false;
    document.getElementById("sample-title").textContent =
      `Sample ${index}: ${sample.key} (${sample.width} x ${sample.height}, ${sample.masks} materials)`;
    const part = (name, extra = {}) => apiUrl("/api/sample/image", { root: state.root, index, part: name, ...extra });
    const pictures = [figure(part("image"), "image"), figure(part("overlay"), "annotation over the image"),
      figure(part("annotation"), "annotation (soft, as trained)")];
    for (let k = 0; k < sample.masks; k++) {
      pictures.push(figure(part("mask", { mask: k }), `material ${k}`, PALETTE[k % PALETTE.length]));
    }
    if (sample.roi) pictures.push(figure(part("roi"), "ROI"));
    document.getElementById("pictures").replaceChildren(...pictures);
    document.getElementById("meta").textContent = sample.meta ? JSON.stringify(sample.meta, null, 2) : "(none)";
    const link = document.getElementById("segment-link");
    link.href = `/?${new URLSearchParams({ ...Object.fromEntries(new URLSearchParams(location.search)),
      root: state.root, path: `sample/${index}` })}`;
    detail.dataset.index = index;
    say(`sample ${index} (of ${state.total}, numbered 0 to ${state.total - 1})`);
  } catch (error) {
    say(error.message, true);
  }
}

async function openDataset(dataset) {
  state.root = dataset.root;
  state.total = dataset.samples;
  document.getElementById("goto").max = String(Math.max(0, dataset.samples - 1));
  document.getElementById("summary").textContent =
    `${dataset.folder}: ${dataset.samples} samples` + (dataset.incomplete ? `, ${dataset.incomplete} incomplete left out` : "");
  await showPage(0);
}

document.getElementById("previous").addEventListener("click", () => showPage(state.offset - PAGE));
document.getElementById("next").addEventListener("click", () => {
  if (state.offset + PAGE < state.total) showPage(state.offset + PAGE);
});
document.getElementById("goto").addEventListener("change", (event) => {
  const text = event.target.value.trim();
  const index = Number(text);
  if (!state.root) {
    say("No dataset to show a sample of.", true);
  } else if (text === "" || !Number.isInteger(index) || index < 0 || index >= state.total) {
    const range = state.total ? `0 to ${state.total - 1}` : "none: it is empty";
    say(`Sample ${text || "(none)"}: no such sample; this dataset's are numbered ${range}.`, true);
  } else {
    showSample(index);
  }
});
document.getElementById("back").addEventListener("click", () => showPage(state.offset));

const { datasets } = await (await api("/api/datasets")).json();
if (!datasets.length) {
  say("No dataset: start the server with --data FOLDER (MatSeg sample folders or .tar shards).", true);
}
listFolders(select, datasets);
select.addEventListener("change", () => openDataset(datasets.find((d) => d.root === select.value)));
if (datasets.length) openDataset(datasets[0]);
