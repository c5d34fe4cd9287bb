// The lookfeel page: upload (or pick) an image, show the ranked fabrics. No libraries.
// The server's Content-Security-Policy refuses inline styles and scripts: never set a `style`
// attribute (el() refuses one); set a property of `element.style` instead (bar() does).
"use strict";

const $ = (sel) => document.querySelector(sel);
const NAMES = { depth: "looks (depth)", color: "looks (colour)", touch: "feels (touch)" };
let info = null;
// Seconds to wait for an answer before giving up: generous, as the first query may load the
// model. A `let`, so that a test can shorten it.
let answerTimeoutS = 120;

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "style") throw new Error("inline styles are blocked by the page's CSP: use element.style");
    if (k === "class") e.className = v; else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return e;
}

// Say how things stand. An error goes to #error (role="alert", read out at once), anything
// else to #status (role="status", read out politely); the other one is emptied.
function status(text, kind) {
  const s = $("#status"), e = $("#error");
  if (kind === "error") {
    s.textContent = ""; s.className = "";
    e.textContent = text;
  } else {
    e.textContent = "";
    s.textContent = text; s.className = kind || "";
  }
}

// Mark the file input wrong (an error about the chosen files) or right again: aria-invalid,
// and the error added to what describes it.
function filesInvalid(invalid) {
  const f = $("#files");
  if (invalid) {
    f.setAttribute("aria-invalid", "true");
    f.setAttribute("aria-describedby", "error files-hint");
  } else {
    f.removeAttribute("aria-invalid");
    f.setAttribute("aria-describedby", "files-hint");
  }
}

// A failed request, with the line the page shows for it and the HTTP status (0 for none).
class Failure extends Error {
  constructor(text, code = 0) { super(text); this.code = code; }
}

// GET or POST `url` and return its JSON answer, or throw a Failure saying what went wrong in
// words: the server's own message (its JSON `detail`), a server or proxy that failed without
// JSON, no server to reach, or no answer in `answerTimeoutS` seconds.
async function fetchJSON(url, options = {}) {
  const abort = new AbortController();
  const timer = setTimeout(() => abort.abort(), 1000 * answerTimeoutS);
  let r, data = null;
  try {
    r = await fetch(url, { ...options, signal: abort.signal });
    const text = await r.text();  // the wait for the body counts in the timeout too
    if (/\bjson\b/i.test(r.headers.get("content-type") || "")) {
      try { data = JSON.parse(text); } catch { data = null; }
    }
  } catch (e) {
    if (abort.signal.aborted) {
      throw new Failure(`Error: no answer from the server in ${answerTimeoutS} s; ` +
                        "is lookfeel serve still running? Try again.");
    }
    throw new Failure("Error: cannot reach the server (is lookfeel serve still running?)");
  } finally {
    clearTimeout(timer);
  }
  const said = data && data.detail;
  if (!r.ok && said !== undefined && said !== null) {
    throw new Failure(`Error ${r.status}: ${typeof said === "string" ? said : JSON.stringify(said)}`, r.status);
  }
  const answer = `HTTP ${r.status}${r.statusText ? " " + r.statusText : ""}`;
  if (!r.ok) throw new Failure(`Error: the server failed (${answer})`, r.status);
  if (data === null) throw new Failure(`Error: the server's answer is not JSON (${answer})`, r.status);
  return data;
}

// Sizes as people read them: 8 MB, 0.5 MB.
function mb(bytes) {
  return `${g(bytes / (1024 * 1024))} MB`;
}

// Why the chosen files cannot be sent (the server's limits, from /api/library), or "".
function tooBig(files) {
  const limits = info && info.limits;
  if (!limits) return "";
  if (files.length > limits.max_files) {
    return `${files.length} files chosen; at most ${limits.max_files} per query`;
  }
  for (const f of files) {
    if (f.size > limits.max_upload_bytes) {
      const [size, most] = mb(f.size) === mb(limits.max_upload_bytes)
        ? [`${f.size} bytes`, `${limits.max_upload_bytes} bytes`]
        : [mb(f.size), mb(limits.max_upload_bytes)];
      return `${f.name}: ${size}; at most ${most} per file`;
    }
  }
  return "";
}

function fmt(x, digits = 3) {
  return x === null || x === undefined ? "?" : Number(x).toPrecision(digits);
}

// A fabric by its name where the data names its objects ("sponge"), else by id ("fabric 7").
function title(f) {
  return f.name === null || f.name === undefined ? `fabric ${f.fabric_id}` : f.name;
}

// A number as Python's "%.<digits>g" writes it, as `lookfeel match` prints: 1.4, 0, 2.
function g(x, digits = 3) {
  return x === null || x === undefined ? "?" : String(Number(Number(x).toPrecision(digits)));
}

// A property estimate (a label column and its entry of `properties`, shaped as `lookfeel
// predict`'s) as `lookfeel match` prints it: "hardness 2 (87%)" for a column of classes (it has
// a probability), "thickness_mm 1.43 ± 0.3" for a number.
function property([name, p]) {
  if (p.probability !== null && p.probability !== undefined) return `${name} ${p.value} (${Math.round(100 * p.probability)}%)`;
  return `${name} ${g(p.value)} ± ${g(p.std, 2)}`;
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
  info = await fetchJSON("/api/library");
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
  if (info.limits) {
    const { max_files: most, max_upload_bytes: each } = info.limits;
    $("#limits").textContent = ` Up to ${most} file${most === 1 ? "" : "s"} a query, at most ${mb(each)} each.`;
  }
  const fabrics = await fetchJSON("/api/fabrics?per_modality=1");
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
  filesInvalid(false);
  for (const f of $("#files").files) {
    if ($("#modality").value === "depth" || isVideo(f)) p.append(el("span", { class: "file" }, f.name));
    else p.append(el("img", { src: URL.createObjectURL(f), alt: f.name }));
  }
}

// A probability bar: its width set through the CSSOM, which the CSP allows (a `style`
// attribute it would block, leaving every bar full width).
// Hidden from screen readers: the P printed beside it says the same.
function bar(probability) {
  const fill = el("div");
  fill.style.width = `${(100 * probability).toFixed(1)}%`;
  return el("div", { class: "bar", "aria-hidden": "true" }, fill);
}

// What the properties are, as `lookfeel match` labels them: the likeliest fabrics' labels
// weighted by P (not the model's property heads, which `lookfeel predict` answers).
// "object" for a library of named objects (sponge), else "fabric", as `lookfeel match` says.
function nounOf(res) {
  return res.fabrics.some((f) => f.name !== null && f.name !== undefined) ? "object" : "fabric";
}

function propertiesLabel(res) {
  const noun = nounOf(res);
  const k = res.property_fabrics;
  const likeliest = k === 1 ? `the likeliest ${noun}` : `the ${k} likeliest ${noun}s`;
  const guess = res.known ? "" : `; no known ${noun}: the nearest ones', a guess`;
  return `Properties (${likeliest} weighted by P${guess})`;
}

// A file the server could not use, among others it matched (its `error`, one line naming it:
// empty, not a PNG or JPEG, undecodable, ...): its name and why, as an error, in a card of its
// own.
function renderFailure(res) {
  return el("div", { class: "result failed" },
    el("h2", {}, `${res.query_modality} query (${res.paths.join(", ")}): not matched`),
    el("p", { class: "why" }, res.error));
}

function renderResult(res) {
  if (res.error) return renderFailure(res);
  const box = el("div", { class: "result" });
  const what = res.presses > 1 ? `${res.presses} presses` : res.paths.join(", ");
  box.append(el("h2", {}, `${res.query_modality} query (${what}) against ${res.gallery_modality}`));
  const props = Object.entries(res.properties).filter(([, p]) => p.value !== null).map(property);
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
        // The caption says what the image is (the file's name shown, not only on hover), so
        // the image's own alt would say it twice: it is left empty.
        const file = ref.path.split(/[\\/]/).pop();
        views.append(el("figure", {},
          el("img", { src: `/api/items/${ref.id}/image`, alt: "", title: ref.path }),
          el("figcaption", {}, NAMES[m] || m, el("br"), el("span", { class: "path" }, file))));
      }
    }
    box.append(el("div", { class: "fabric" }, left, views));
  }
  return box;
}

// One result's verdict in a few words, for a status line that covers several results:
// "a.png: fabric 3 (P = 0.912)", "b.png: no known fabric (best fabric 5, P = 0.301)", or a
// file that could not be used, its error: "c.png: cannot decode the image header (...)".
function verdict(res) {
  const files = res.paths.join(", ");
  if (res.error) return res.error.startsWith(`${files}: `) ? res.error : `${files}: ${res.error}`;
  const best = res.fabrics[0];
  const name = best ? title(best) : "none";
  const said = res.known ? `${name} (P = ${fmt(res.best_probability)})`
    : `no known ${nounOf(res)} (best ${name}, P = ${fmt(res.best_probability)})`;
  return `${files}: ${said}`;
}

function show(data) {
  const results = $("#results");
  results.replaceChildren(...data.results.map(renderResult));
  const first = data.results[0];
  // What `lookfeel match` warns of the files: one left out of a pooled query (a press video
  // without a press), a press of another kind, a turned query, a press video with no colour.
  const notes = (data.warnings || []).map((w) => ` Note: ${w}.`).join("");
  const known = data.results.filter((r) => r.known).length;
  const kind = known === data.results.length ? "known" : known === 0 ? "unknown" : "";
  if (data.results.length > 1) {
    // Every result, briefly (each card's heading names its files; the cards say the rest),
    // a file that could not be used by its error.
    status(`${data.results.length} results: ${data.results.map(verdict).join("; ")}.` + notes, kind);
  } else if (first.error) {
    status(verdict(first) + notes, "unknown");
  } else if (first.known) {
    status(first.message + notes, kind);
  } else {
    status(first.message.charAt(0).toUpperCase() + first.message.slice(1) + notes, kind);
  }
}

// Send a query and show its answer. The previous results go first, so that an error (or a
// wait) never leaves them on screen as if they answered this query. `upload`: an error about
// the request (413, 415, 422) is about the chosen files, and marks the file input so.
async function submit(url, options, upload = false) {
  const results = $("#results");
  results.replaceChildren();
  results.setAttribute("aria-busy", "true");
  $("#match").disabled = $("#match-item").disabled = true;
  status("Matching…");
  try {
    show(await fetchJSON(url, options));
  } catch (e) {
    results.replaceChildren();
    status(e instanceof Failure ? e.message : `Error: ${e}`, "error");
    if (upload && [413, 415, 422].includes(e.code)) filesInvalid(true);
  } finally {
    results.setAttribute("aria-busy", "false");
    $("#match").disabled = $("#match-item").disabled = false;
  }
}

$("#files").addEventListener("change", showPreview);
$("#modality").addEventListener("change", showPreview);
$("#upload-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  const files = $("#files").files;
  const wrong = files.length ? tooBig(files) : "Choose one or more images first.";
  if (wrong) {
    $("#results").replaceChildren();
    status(files.length ? `Error: ${wrong}` : wrong, "error");
    filesInvalid(true);
    return;
  }
  filesInvalid(false);
  const body = new FormData();
  body.append("modality", $("#modality").value);
  body.append("top", $("#top").value);
  for (const f of files) body.append("files", f);
  submit("/api/match", { method: "POST", body }, true);
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
loadLibrary().catch((e) => status(`Cannot read the library: ${e instanceof Failure ? e.message : e}`, "error"));
