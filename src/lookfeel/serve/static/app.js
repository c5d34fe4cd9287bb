// The lookfeel page: upload (or pick) an image, show the ranked fabrics. No libraries.
// The server's Content-Security-Policy refuses inline styles and scripts: never set a `style`
// attribute (el() refuses one); set a property of `element.style` instead (bar() does).
"use strict";

const $ = (sel) => document.querySelector(sel);
const NAMES = { depth: "looks (depth)", color: "looks (colour)", touch: "feels (touch)" };
let info = null;

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "style") throw new Error("inline styles are blocked by the page's CSP: use element.style");
    if (k === "class") e.className = v; else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return e;
}

function status(text, kind) {
  const s = $("#status");
  s.textContent = text;
  s.className = kind || "";
}

function fmt(x, digits = 3) {
  return x === null || x === undefined ? "?" : Number(x).toPrecision(digits);
}

// A fabric by its name where the data names its objects ("sponge"), else by id ("fabric 7").
function title(f) {
  return f.name === null || f.name === undefined ? `fabric ${f.fabric_id ?? f.id}` : f.name;
}

// A number as Python's "%.<digits>g" writes it, as `lookfeel match` prints: 1.4, 0, 2.
function g(x, digits = 3) {
  return x === null || x === undefined ? "?" : String(Number(Number(x).toPrecision(digits)));
}

// A property estimate as `lookfeel match` prints it: "hardness 2 (87%)" for a column of
// classes, "thickness_mm 1.43 ± 0.3" for a number.
function property(p) {
  if (p.value !== null && p.value !== undefined) return `${p.name} ${p.value} (${Math.round(100 * p.probability)}%)`;
  return `${p.name} ${g(p.mean)} ± ${g(p.std, 2)}`;
}

// A fabric's labels: the numbers (a rank or class as the whole number it is: hardness 2), then
// the words (material) it also has.
function labels(f) {
  const text = f.text_labels || {};
  const words = Object.entries(text).filter(([k]) => !(k in f.labels));
  return [...Object.entries(f.labels).map(([k, v]) => `${k} ${g(v)}`),
          ...words.map(([k, v]) => `${k} ${v}`)].join(" · ");
}

// Whether an upload is a press video, by its type or its name.
const VIDEO_NAME = /\.(mov|mp4|avi|mkv|webm|m4v)$/i;
function isVideo(file) {
  return (file.type || "").startsWith("video/") || VIDEO_NAME.test(file.name);
}

async function loadLibrary() {
  const r = await fetch("/api/library");
  info = await r.json();
  const items = Object.entries(info.items).map(([m, n]) => `${n} ${m}`).join(", ");
  $("#library").textContent =
    `${info.fabrics} fabrics (${items}); model ${info.backbone} at ${info.image_size} px` +
    (info.color_size ? ` (colour ${info.color_size} px)` : "") + ", " +
    `D = ${info.embed_dim}; search ${info.backend}.`;
  for (const opt of $("#modality").options) {
    opt.disabled = !(info.uploads || info.modalities).includes(opt.value);
    if (info.modalities.includes(opt.value) && opt.disabled) {
      opt.textContent += " — this model reads several frames of a press: pick a library press below";
    }
  }
  const first = [...$("#modality").options].find((o) => !o.disabled);
  if (first && $("#modality").selectedOptions[0]?.disabled) $("#modality").value = first.value;
  const fabrics = await (await fetch("/api/fabrics?per_modality=1")).json();
  const pick = $("#pick");
  for (const f of fabrics) {
    for (const [m, ids] of Object.entries(f.items)) {
      for (const id of ids) pick.append(el("option", { value: id }, `${title(f)}: ${m} (${id})`));
    }
  }
}

function showPreview() {
  // Browsers draw a 16-bit depth map (millimetres) nearly black, and an <img> cannot show a
  // press video, so depth and videos show their names only.
  const p = $("#preview");
  p.replaceChildren();
  for (const f of $("#files").files) {
    if ($("#modality").value === "depth" || isVideo(f)) p.append(el("span", { class: "file" }, f.name));
    else p.append(el("img", { src: URL.createObjectURL(f), alt: f.name }));
  }
}

// A probability bar: its width set through the CSSOM, which the CSP allows (a `style`
// attribute it would block, leaving every bar full width).
function bar(probability) {
  const fill = el("div");
  fill.style.width = `${(100 * probability).toFixed(1)}%`;
  return el("div", { class: "bar" }, fill);
}

// What the properties are, as `lookfeel match` labels them: the likeliest fabrics' labels
// weighted by P (not the model's property heads, which `lookfeel predict` answers).
function propertiesLabel(res) {
  const noun = res.fabrics.some((f) => f.name !== null && f.name !== undefined) ? "object" : "fabric";
  const k = res.property_fabrics;
  const likeliest = k === 1 ? `the likeliest ${noun}` : `the ${k} likeliest ${noun}s`;
  const guess = res.known ? "" : `; no known ${noun}: the nearest ones', a guess`;
  return `Properties (${likeliest} weighted by P${guess})`;
}

function renderResult(res) {
  const box = el("div", { class: "result" });
  const what = res.presses > 1 ? `${res.presses} presses` : res.query.join(", ");
  box.append(el("h2", {}, `${res.query_modality} query (${what}) against ${res.gallery_modality}`));
  const props = res.properties.filter((p) => p.mean !== null || p.value !== null).map(property);
  if (props.length) box.append(el("p", { class: "props" }, propertiesLabel(res) + ": " + props.join(" · ")));
  for (const f of res.fabrics) {
    const left = el("div", {},
      el("h3", {}, `#${f.rank} ${title(f)}`),
      el("div", { class: "p" }, `P = ${fmt(f.probability)}`),
      bar(f.probability),
      el("div", { class: "meta" }, `D = ${fmt(f.distance)}` + (f.cluster !== null ? ` · cluster ${f.cluster}` : "")),
      el("div", { class: "meta" }, labels(f)));
    const views = el("div", { class: "views" });
    for (const [m, refs] of Object.entries(f.nearest)) {
      for (const ref of refs.slice(0, 1)) {
        views.append(el("figure", {},
          el("img", { src: `/api/items/${ref.id}/image`, alt: `${m} of ${title(f)}`, title: ref.path }),
          el("figcaption", {}, NAMES[m] || m)));
      }
    }
    box.append(el("div", { class: "fabric" }, left, views));
  }
  return box;
}

function show(data) {
  const results = $("#results");
  results.replaceChildren(...data.results.map(renderResult));
  const first = data.results[0];
  // What `lookfeel match` warns of the files: one left out of a pooled query (a press video
  // without a press), a press of another kind, a turned query, a press video with no colour.
  const notes = (data.warnings || []).map((w) => ` Note: ${w}.`).join("");
  if (data.results.every((r) => r.known)) status(first.message + notes, "known");
  else status(first.message.charAt(0).toUpperCase() + first.message.slice(1) + notes, "unknown");
}

async function submit(url, options) {
  $("#match").disabled = $("#match-item").disabled = true;
  status("Matching…");
  try {
    const r = await fetch(url, options);
    const data = await r.json();
    if (!r.ok) {
      $("#results").replaceChildren();
      status(`Error ${r.status}: ${typeof data.detail === "string" ? data.detail : JSON.stringify(data.detail)}`, "error");
      return;
    }
    show(data);
  } catch (e) {
    status(`Error: ${e}`, "error");
  } finally {
    $("#match").disabled = $("#match-item").disabled = false;
  }
}

$("#files").addEventListener("change", showPreview);
$("#modality").addEventListener("change", showPreview);
$("#upload-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  const files = $("#files").files;
  if (!files.length) { status("Choose one or more images first.", "error"); return; }
  const body = new FormData();
  body.append("modality", $("#modality").value);
  body.append("top", $("#top").value);
  for (const f of files) body.append("files", f);
  submit("/api/match", { method: "POST", body });
});
$("#pick-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  const item = $("#pick").value;
  if (!item) return;
  submit("/api/match/item", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ item, top: Number($("#top").value) }),
  });
});
loadLibrary().catch((e) => status(`Cannot read the library: ${e}`, "error"));
