// raycast-phong view: controls → {dotted scene key: value} over the socket; frames back as PNG.
// The server validates every value with the scene schema and renders; this page only shows what it gets.
"use strict";

// The token opens the page once: the server sets its cookie, and the token leaves the address bar, so that a
// copied URL or permalink carries settings only (sharing a view never shares access). A page framed by a
// notebook keeps it: its frame's URL is nobody's to copy, and a notebook of another site gets no cookie.
const token = new URLSearchParams(location.search).get("token") || "";
if (token && window.top === window) {
  const query = new URLSearchParams(location.search);
  query.delete("token");
  history.replaceState(null, "", `${location.pathname}${query.size ? `?${query}` : ""}${location.hash}`);
}
const withToken = (path) => (token ? `${path}?token=${encodeURIComponent(token)}` : path);
const $ = (selector) => document.querySelector(selector);
const state = {
  hello: null,
  settings: { a: {}, b: {} },  // B is set from A when a comparison is first asked for
  bStarted: false,
  editing: "a",
  level: { a: null, b: null },  // the tessellation slider's level, or null: as the scene says
  compare: "off",
  nextId: 1,
  shownId: 0,      // newest frame on screen; older replies are ignored
  inputTimes: {},  // request id → time of the oldest input it answers, for the input → image latency
  sendTimes: {},   // request id → time it was sent
  urls: {},        // object URLs on screen, revoked when replaced
  lastFrame: null, // header of the frame on screen (tests read it)
  connected: false,
  painted: [],     // the frames shown: {id, quality, ms, sent, shown, server, at} (onFrame says which is which)
  answered: 0,     // newest request answered (by a frame or an error)
  asked: null,     // {id, quality, at} of the newest request (sent, or waiting to be)
  warming: false,  // the server is still loading or compiling its kernels
  want: null,      // {id, quality}: the newest state, not yet sent (sent on the next display frame)
  inputAt: null,   // time of the oldest input the next request sent will answer
  inFlight: [],    // {id, quality} of the requests sent and not yet answered: DRAFTS_IN_FLIGHT drafts at most
  previewed: 0,    // id of the request whose preview (one sample a pixel) is on screen
};
window.view = state;  // for the browser tests and the screenshot script

// ------------------------------------------------------------------ socket

// A lost server disables the controls and dims the image behind a banner; the page then tries again every
// second or two, and a server restarted on the same port (it keeps its token) picks up where this one was:
// the settings stay in the page and are sent again with the next frame.
let socket = null;
let retries = 0;
function connect() {
  socket = new WebSocket(`ws://${location.host}${withToken("/socket")}`);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => {
    retries = 0;
    connected(true, "connected");
  };
  socket.onclose = async (event) => {
    const wasOpen = state.connected;
    state.inFlight = [];  // their answers will never come: the state is sent again on reconnecting
    // A socket refused before its upgrade reaches the page as 1006, like a server that is down: ask why.
    const refused = event.code === 1008 || (!wasOpen && await tokenRefused());
    state.refused = refused;
    connected(false, refused
      ? "the server refused this page's token (a server started with another one?): open the URL the view " +
        "command printed"
      : `the server is not answering (${wasOpen ? `closed, code ${event.code}` : "no connection"}); ` +
        "the controls are off until it is back; trying again…");
    retries += 1;
    // Refused: a server with another token; asking again cannot help until the page is opened anew.
    if (!refused) setTimeout(connect, Math.min(2000, 250 * 2 ** retries));
  };
  socket.onmessage = onMessage;
}

// True when the server answers and refuses this page's token (or cookie); false when it does not answer.
async function tokenRefused() {
  try {
    return (await fetch(withToken("/access"), { cache: "no-store" })).status === 403;
  } catch (error) {
    return false;
  }
}

function connected(on, text) {
  state.connected = on;
  $("#connection").textContent = on ? "connected" : "disconnected";
  $("#connection").classList.toggle("lost", !on);
  $("#lost").hidden = on;
  $("#lost").textContent = on ? "" : text;
  $("#controls").inert = !on;
  for (const box of document.querySelectorAll("#controls fieldset")) box.disabled = !on || box.dataset.off === "1";
  $("#viewer").classList.toggle("lost", !on);
}

function onMessage(event) {
  const arrived = performance.now();
  if (typeof event.data === "string") return onText(JSON.parse(event.data));
  const view = new DataView(event.data);
  const length = view.getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(event.data, 4, length)));
  const parts = {};
  let at = 4 + length;
  for (const part of header.parts) {
    parts[part.name] = new Uint8Array(event.data, at, part.length);
    at += part.length;
  }
  if (header.type === "frame") onFrame(header, parts, arrived);
  else if (header.type === "saved") download(header.filename, parts.file);
}

function onText(message) {
  if (message.type === "hello") return onHello(message);
  if (message.type === "loaded") {
    // A scene file opened on the page: its settings replace those of the side being edited.
    state.settings[state.editing] = message.settings;
    state.level[state.editing] = null;
    refreshControls();
    request("full");
    return;
  }
  if (message.type === "progress") {
    if (state.asked && message.id === state.asked.id) $("#busy-bar").value = message.done;
    return;
  }
  if (message.type === "cancelled" || message.type === "dropped") {
    settled(message.id);  // the newer request that made it stale is on its way
    return;
  }
  if (message.type === "error" && message.file) {
    // The scene file is invalid: said until the file is valid again (the next hello), whatever frames come.
    $("#file-error").textContent = message.message;
    $("#file-error").hidden = false;
    return;
  }
  if (message.type === "error") {
    settled(message.id);
    state.answered = Math.max(state.answered, message.id ?? 0);
    busy();
    if (message.id === null || message.id >= state.shownId) showError(message.message);
  } else if (message.type === "errors" && message.id === state.shownId) {
    const pct = (x) => (x === null ? "–" : `${(100 * x).toFixed(1)} %`);
    const num = (x) => (x === null ? "–" : x.toFixed(4));
    $("#exact").textContent = `RMSE ${num(message.rmse)}, max ${num(message.max_error)}, ` +
      `highlight loss ${pct(message.highlight_loss)} (reference ${(1000 * message.seconds).toFixed(0)} ms)`;
  }
}

// A message larger than the server takes (hello's limits) is answered here in one line, as the server would.
function send(message) {
  if (socket.readyState !== WebSocket.OPEN) return;
  const text = JSON.stringify(message), most = state.hello?.limits.message_bytes ?? Infinity;
  const size = new TextEncoder().encode(text).length;
  if (size > most) {
    return onText({ type: "error", id: message.id ?? null, message: `message of ${grouped(size)} bytes; allowed: at most ${grouped(most)}` });
  }
  socket.send(text);
}

// Asking for a frame. A draft (while dragging): the newest state is sent on the next display frame
// (requestAnimationFrame), and only while no draft is unanswered (DRAFTS_IN_FLIGHT; two, the server keeping the
// next state waiting, measured no better on this 2-core machine: docs/view.md); inputs in between are folded into
// it (its settings are read when it is sent), and it goes as soon as the draft in flight is answered. So a burst
// of pointer events makes one request a display frame at most, and fewer when the frames take longer.
// A full frame (a release, a key, a field: a committed change) is sent at once, whatever is in flight, and is
// never folded into a later draft: the server renders it before a draft that follows, and the page paints it
// before that draft (issue 35: every release is seen, even when the next stroke starts at once).
// The URL is written for full frames only, which a drag asks for when it ends, never per pointer event.
const DRAFTS_IN_FLIGHT = 1;
function request(quality) {
  if (!state.connected) return null;  // the settings stay; the frame is asked for on reconnecting
  if (quality === "full") { permalink(); remember(); }
  const id = state.nextId++;
  const event = window.event;  // the input being handled: its time, not this handler's, starts the latency
  const coalesced = event && event.getCoalescedEvents ? event.getCoalescedEvents() : [];
  const at = Math.min(event ? (coalesced.length ? coalesced[0].timeStamp : event.timeStamp) : performance.now(),
                      performance.now());
  state.asked = { id, quality, at: performance.now() };
  $("#busy-bar").removeAttribute("value");  // indeterminate until the first tiles are done
  if (quality === "full") {
    // The draft not yet sent is answered by this frame (its settings are in it); the latency counts from the
    // release (or key, or field) itself.
    state.want = null;
    state.inputAt = null;
    if (socket.readyState === WebSocket.OPEN) sendRequest({ id, quality }, at);
    return id;
  }
  if (state.inputAt === null) state.inputAt = at;
  state.want = { id, quality };
  nextDisplayFrame();
  return id;
}
state.request = request;

// Once per display frame: the light's gizmo, fields and marker redrawn if a change asked for it, then the
// newest state sent if nothing blocks it. A page the browser does not draw (a hidden tab, a notebook's frame
// scrolled away) gets no animation frames: a timer stands in after 100 ms.
let displayFrameAsked = false, redrawWanted = false;
function nextDisplayFrame() {
  if (displayFrameAsked) return;
  displayFrameAsked = true;
  let timer = null;
  const run = () => {
    if (!displayFrameAsked) return;  // the other of the two came first
    displayFrameAsked = false;
    clearTimeout(timer);
    if (redrawWanted) { redrawWanted = false; refreshLight(); }
    flush();
  };
  requestAnimationFrame(run);
  timer = setTimeout(run, 100);
}
function redrawLight() { redrawWanted = true; nextDisplayFrame(); }

function flush() {
  const want = state.want;
  if (!want || !state.connected || socket.readyState !== WebSocket.OPEN) return;
  if (state.inFlight.filter((r) => r.quality === "draft").length >= DRAFTS_IN_FLIGHT) return;  // one comes soon
  state.want = null;
  sendRequest(want, state.inputAt ?? performance.now());
  state.inputAt = null;
}

function sendRequest(want, inputAt) {
  state.inFlight.push(want);
  state.inputTimes[want.id] = inputAt;
  state.sendTimes[want.id] = performance.now();
  const models = state.compare === "models";
  send({
    type: "render", id: want.id, quality: want.quality, models,
    settings: state.settings.a,
    compare: state.compare === "off" || models ? null : state.settings.b,
    reference: Boolean(state.hello && state.hello.analytic) && want.quality === "full" && !models,
    pixels: want.quality === "draft" || LOCAL ? "rgba" : "png",  // raw pixels go straight into the canvas
  });
}

// Every frame as raw pixels when the server is on this machine: a full frame's PNG cost the server ~7 ms to
// encode and the page 21-32 ms from arrival to paint (createImageBitmap) against under a millisecond raw, a
// release's wait. From another machine a full frame stays a PNG (640×360 raw is 0.9 MB, 74 ms on 100 Mbit/s).
const LOCAL = ["127.0.0.1", "localhost", "[::1]"].includes(location.hostname);

// The request `id` is answered (its final frame, an error, dropped or cancelled): the newest state may go, at
// once (a display frame later would leave the server idle meanwhile).
function settled(id) {
  const before = state.inFlight.length;
  state.inFlight = state.inFlight.filter((r) => r.id !== id);
  if (state.inFlight.length < before && state.want) flush();
}

// ------------------------------------------------------------------ frames

// A panel's newest full-frame PNG, kept as an object URL (`state.urls`, by the panel's <img> id) for capture (a raw
// full frame keeps none: capture then asks the server for the PNG, forget). It is
// not the <img>'s src: that image (transparent, under the canvas) only takes the pointer and gives the panel its
// box (--aspect), and as its src Chromium decoded every full frame a second time beside createImageBitmap
// (issue 35: arrival → canvas 13–22 ms → 6–10 ms for a 1.11M-triangle scan's release).
function keep(id, bytes) {
  const url = URL.createObjectURL(new Blob([bytes], { type: "image/png" }));
  if (state.urls[id]) URL.revokeObjectURL(state.urls[id]);
  state.urls[id] = url;
  return url;
}
function forget(id) {
  if (state.urls[id]) URL.revokeObjectURL(state.urls[id]);
  delete state.urls[id];
}
function show(img, bytes) { img.src = keep(img.id, bytes); }  // the heat map: an <img> on screen

// What is on screen is each panel's canvas: raw pixels go into it at once; a full frame's (or a preview's) PNG
// is decoded off the main thread (createImageBitmap) and drawn into it, and kept for capture (keep).
// A full frame (or a preview) is painted before any later frame replaces it: frames that arrive meanwhile wait
// (`held`) until the display frame that shows it has been drawn (a task after its animation frame callbacks: the
// browser draws that frame between the two), and a draft among them is skipped when a newer frame waits behind it.
let holding = false;
const held = [];
function painted() {
  holding = false;
  while (!holding && held.length) {
    const next = held.shift();
    if (next[0].quality === "draft" && held.length) continue;  // a newer frame waits: this draft is stale
    onFrame(...next);
  }
}

// One panel's frame into its canvas: raw RGBA rows (top first) of a draft, or a decoded full frame.
function paintPanel(name, header, image) {
  const canvas = $(`#canvas-${name}`);
  const { width, height } = header.stats[name];
  if (canvas.width !== width) canvas.width = width;
  if (canvas.height !== height) canvas.height = height;
  const context = canvas.getContext("2d");
  if (image instanceof Uint8Array) {
    const pixels = new Uint8ClampedArray(image.buffer, image.byteOffset, image.length);
    context.putImageData(new ImageData(pixels, width, height), 0, 0);
  } else {
    context.drawImage(image, 0, 0);
    image.close();
  }
  canvas.hidden = false;
}

function onFrame(header, parts, arrived = performance.now()) {
  const preview = header.quality === "preview";  // one sample a pixel; the full frame of the same request follows
  if (!preview) settled(header.id);
  if (header.id < state.shownId) return;
  if (holding) { held.push([header, parts, arrived]); return; }
  state.shownId = header.id;
  if (preview) state.previewed = header.id; else state.answered = Math.max(state.answered, header.id);
  state.warming = false;
  busy();
  // The images fill the room there is (the stylesheet), as tall as the window allows; a draft (fewer pixels) is
  // shown at the full frame's size; side by side, each gets its share.
  const panels = { side: 2, models: 3 }[state.compare] || 1;
  const stage = $("#stage").style, aspect = String(valueOf("render.width") / valueOf("render.height"));
  if (stage.getPropertyValue("--aspect") !== aspect) stage.setProperty("--aspect", aspect);  // restyles the stage
  if (stage.getPropertyValue("--panels") !== String(panels)) stage.setProperty("--panels", panels);
  const raw = header.pixels === "rgba";
  const panelsSent = ["a", "b", "c"].filter((name) => parts[name]);
  for (const name of panelsSent) {
    const img = $(`#image-${name}`);
    if (!raw) keep(img.id, parts[name]);
    else if (header.quality !== "draft") forget(img.id);  // capture asks the server for this frame's PNG
    img.dataset.id = header.id;
    img.dataset.quality = header.quality;
  }
  const images = raw ? Promise.resolve(panelsSent.map((name) => parts[name]))
    : Promise.all(panelsSent.map((name) => createImageBitmap(new Blob([parts[name]], { type: "image/png" }))));
  const holds = header.quality !== "draft";  // painted before any later frame replaces it
  if (holds) holding = true;
  // Input → on screen: from the oldest input event the frame answers (its own time, as the browser stamped it)
  // to the first animation frame after its pixels are in the canvas, the frame the browser then paints (`ms`);
  // `sent` counts from sending the request, `shown` from the frame's arrival, `server` is the server's own time,
  // `decode` from arrival to drawn. benchmarks/bench_view.py --browser reads these.
  const input = state.inputTimes[header.id], sentAt = state.sendTimes[header.id];
  images.then((decoded) => {
    panelsSent.forEach((name, k) => paintPanel(name, header, decoded[k]));
    const at = performance.now();
    requestAnimationFrame(() => {
      if (holds) setTimeout(painted, 0);
      if (input === undefined) return;
      const now = performance.now(), ms = now - input;
      if (readoutDue("latency", header.quality)) setText("#latency", `${ms.toFixed(0)} ms`);
      state.painted.push({ id: header.id, quality: header.quality, ms, sent: now - sentAt, shown: now - arrived,
                           server: header.seconds * 1000, at: now, decode: at - arrived, wait: sentAt - input });
      if (state.painted.length > 2000) state.painted.shift();
    });
  }, painted);  // it could not be decoded: the frames after it go on
  for (const id of Object.keys(state.inputTimes)) {
    if (Number(id) < header.id || (Number(id) === header.id && !preview)) {  // a preview's full frame follows
      delete state.inputTimes[id];
      delete state.sendTimes[id];
    }
  }
  if (parts.heat) {
    show($("#heat"), parts.heat);
    $("#heat-caption").textContent = `|A − B|, max over RGB: black 0, pale yellow ${header.difference.max.toPrecision(3)}` +
      ` (mean ${header.difference.mean.toPrecision(3)})`;
  } else if (header.difference) {
    $("#heat-caption").textContent = header.difference.note || "";
  }
  readouts(header);
  if (header.quality === "draft" && state.hello.analytic && state.compare !== "models") {
    setText("#exact", "(when the pointer rests)");
  }
  state.lastFrame = header;
  drawMarkers();
  hideError();
}

// A readout's text is written only when it changes: each changed text is laid out and painted again, on the page's
// main thread and in software, beside 30 frames a second of a drag.
function setText(selector, text) {
  const element = $(selector);
  if (element.textContent !== text) element.textContent = text;
}

// Whether a readout that changes with every frame (the times) is written for this one: always for a full frame,
// and at most every READOUT_MS while drafts come.
const READOUT_MS = 250;
const writtenAt = {};
function readoutDue(name, quality) {
  const now = performance.now();
  if (quality === "draft" && now - (writtenAt[name] ?? -Infinity) < READOUT_MS) return false;
  writtenAt[name] = now;
  return true;
}

// The frame's figures (render time, rays, what the plan left out, its warnings), the times as readoutDue says.
function readouts(header) {
  const a = header.stats.a;
  // Compared, each panel's figures: A and B (or the three models), one line each.
  const names = Object.keys(header.stats);
  const label = (name) => (names.length === 1 ? "" : `${$(`#tag-${name}`).textContent}: `);
  if (readoutDue("figures", header.quality)) {
    setText("#frame-time", names.map((name) => { const f = header.stats[name];
      return `${label(name)}${(1000 * f.frame).toFixed(1)} ms render of ${f.width}×${f.height}`; }).join("; ") +
      ` (${header.quality}), ${(1000 * header.seconds).toFixed(1)} ms in all`);
    setText("#rays", names.map((name) => { const f = header.stats[name];
      return `${label(name)}${(f.rays_per_second / 1e6).toFixed(1)} M (${f.rays.toLocaleString()} rays, ` +
        `${f.triangles.toLocaleString()} triangles)`; }).join("; "));
  }
  // What each panel's plan left out: said once when the panels agree, else panel by panel (the three models'
  // plans differ: flat leaves out the vertex normals Phong needs).
  const lists = names.map((name) => header.stats[name].left_out.map((s) => s.name).join(", ") || "nothing");
  const agree = lists.every((list) => list === lists[0]);
  setText("#left-out", agree ? lists[0] : names.map((name, k) => `${label(name)}${lists[k]}`).join("; "));
  const reasons = (agree ? ["a"] : names).map((name) => header.stats[name].left_out
    .map((s) => `${agree ? "" : label(name)}${s.name}: ${s.reason}`).join("\n")).filter(Boolean).join("\n");
  if ($("#left-out").title !== reasons) $("#left-out").title = reasons;
  const warnings = $("#warnings");
  if (warnings.children.length !== a.warnings.length
      || a.warnings.some((w, k) => warnings.children[k].textContent !== w)) {
    warnings.replaceChildren(...a.warnings.map((w) => Object.assign(document.createElement("li"), { textContent: w })));
  }
}

// While a change waits for its image: a bar (the share of tiles done, for full frames), what is being done
// and for how long; the images dim while a full frame is owed. Silent for the first 150 ms (drafts).
function busy() {
  const owed = state.asked && state.asked.id > state.answered && state.connected;
  const waited = owed ? (performance.now() - state.asked.at) / 1000 : 0;
  $("#busy").hidden = !owed || waited < 0.15;
  $("#stage").classList.toggle("stale", Boolean(owed) && waited >= 0.15 && state.asked.quality === "full" &&
                              state.previewed !== state.asked.id);
  if (!owed) return;
  const what = state.warming ? "preparing the renderer (its kernels are compiled on the first run, then cached)"
    : `rendering the ${state.asked.quality} frame`;
  $("#busy-text").textContent = `${what}… ${waited.toFixed(1)} s`;
}
setInterval(busy, 100);

function showError(message) {
  $("#error").textContent = message;
  $("#error").hidden = false;
}
function hideError() { $("#error").hidden = true; }
const grouped = (x) => x.toLocaleString("en-US");  // 60,000: a size as the server's messages say it

function download(filename, bytes) {
  const link = document.createElement("a");
  link.href = URL.createObjectURL(new Blob([bytes]));
  link.download = filename;
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(link.href), 10000);
}

// ------------------------------------------------------------------ settings and controls

function sceneValue(key) {
  let node = state.hello.scene;
  for (const part of key.split(".")) node = node === undefined || node === null ? undefined : node[part];
  return node;
}
function valueIn(side, key) {
  const mine = state.settings[side];
  return key in mine ? mine[key] : sceneValue(key);
}
const valueOf = (key) => valueIn(state.editing, key);
function set(values, quality) {
  Object.assign(state.settings[state.editing], values);
  request(quality);
}

const toHex = (rgb) => "#" + rgb.map((x) => Math.round(255 * Math.min(1, Math.max(0, x))).toString(16).padStart(2, "0")).join("");
const fromHex = (hex) => [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16) / 255);
const shininessOf = (slider) => Number((10 ** Number(slider)).toPrecision(3));  // log scale 1 … 10⁴

function materialKey(coefficient) { return `materials.${$("#material").value}.${coefficient}`; }
function materialValue(coefficient) {
  const key = materialKey(coefficient);
  const mine = state.settings[state.editing];
  return key in mine ? mine[key] : state.hello.material_values[$("#material").value][coefficient];
}

function refreshControls() {
  for (const input of document.querySelectorAll("[data-key]")) {
    input.value = valueOf(input.dataset.key);
    const out = input.parentElement.querySelector("output");
    if (out) out.textContent = input.value;
  }
  $("#shading").value = state.settings[state.editing]["render.shading"] ? valueOf("render.shading") : "";
  const level = state.level[state.editing];
  $("#level").value = level ?? 2;
  $("#level").nextElementSibling.textContent = level ?? "scene";
  refreshLight();
  for (const input of document.querySelectorAll("[data-coefficient]")) {
    input.value = toHex(materialValue(input.dataset.coefficient));
  }
  const shininess = materialValue("shininess");
  $("#shininess").value = Math.log10(Math.min(1e4, Math.max(1, shininess)));
  $("#shininess").nextElementSibling.textContent = shininess;
}

// The shading switch sets every object's own `shading` too: the default figure gives each sphere its own.
function shadingKeys() {
  return ["render.shading", ...state.hello.scene.objects.map((_, i) => `objects.${i}.shading`)];
}

function onHello(message) {
  const again = state.hello !== null;  // a reconnection: keep the light and material chosen
  state.warming = Boolean(message.warming);
  const light = $("#light").value, material = $("#material").value;
  state.hello = message;
  $("#file-error").textContent = message.problem || "";
  $("#file-error").hidden = !message.problem;
  dropStale();
  $("#source").textContent = message.source;
  if (message.reloaded) $("#source").textContent += ` (reloaded ${new Date().toLocaleTimeString()})`;
  $("#material").replaceChildren(...message.materials.map((name) => new Option(name, name)));
  $("#light").replaceChildren(...message.scene.lights.map((light, index) =>
    new Option(`${index + 1}: ${light.type}`, String(index))));
  if (again && message.scene.lights[Number(light)]) $("#light").value = light;
  if (again && message.materials.includes(material)) $("#material").value = material;
  // An exact error exists for analytic shapes only: no promise of a figure that will never come.
  $("#exact-row").hidden = !message.analytic;
  // Meshes have no tessellation level: the slider would change nothing.
  const curved = Object.keys(message.levels[2] || {}).length > 0;
  $("#level").disabled = !curved;
  $("#level").title = curved ? "" : "the scene has no curved shapes to tessellate (meshes are drawn as they are)";
  refreshControls();
  request("full");
}

// Settings the scene no longer has (an object, a light or a material gone from an edited file, or a permalink
// made for another version of it) are dropped, with a note: sent, each frame would be refused.
function applies(key) {
  const found = /^materials\.(.+)\.[^.]+$/.exec(key);
  if (found && state.hello.materials.includes(found[1])) return true;
  return sceneValue(key) !== undefined;
}
function dropStale() {
  const dropped = new Set();
  for (const side of ["a", "b"]) {
    for (const key of Object.keys(state.settings[side])) {
      if (!applies(key)) { delete state.settings[side][key]; dropped.add(key); }
    }
  }
  if (!dropped.size) return;
  const names = [...dropped].sort();
  $("#note").textContent = `settings that no longer apply to ${state.hello.source} were dropped: ` +
    `${names.slice(0, 4).join(", ")}${names.length > 4 ? ` and ${names.length - 4} more` : ""}`;
  $("#note").hidden = false;
}

// ------------------------------------------------------------------ geometry (camera.py's conventions)

const sub = (p, q) => p.map((x, i) => x - q[i]);
const add = (p, q) => p.map((x, i) => x + q[i]);
const scale = (p, s) => p.map((x) => x * s);
const dot = (p, q) => p.reduce((sum, x, i) => sum + x * q[i], 0);
const norm = (p) => Math.hypot(...p);
const unit = (p) => scale(p, 1 / norm(p));
const cross = (p, q) => [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]];
const rounded = (p) => p.map((x) => Number(x.toFixed(6)));  // what the settings (and so the URL) carry

// p turned by `angle` (radians) round the unit `axis` (Rodrigues' formula).
function rotate(p, axis, angle) {
  const c = Math.cos(angle), s = Math.sin(angle);
  return add(add(scale(p, c), scale(cross(axis, p), s)), scale(axis, dot(axis, p) * (1 - c)));
}

// The camera of one side (A or B) as its settings make it: camera_rig's eye, right, up, forward and half sizes.
function rigOf(side) {
  const value = (key) => valueIn(side, key);
  const eye = value("camera.position"), target = value("camera.look_at");
  const forward = unit(sub(target, eye));
  const right = unit(cross(forward, value("camera.up")));
  const up = cross(right, forward);
  const orthographic = value("camera.type") === "orthographic";
  const halfHeight = orthographic ? value("camera.view_height") / 2 : Math.tan((value("camera.fov") * Math.PI) / 360);
  const aspect = value("render.width") / value("render.height");
  return { eye, target, forward, right, up, orthographic, halfHeight, halfWidth: halfHeight * aspect };
}

// Where world point p falls on the image, (u, v) ∈ [0, 1]² from the top left; null behind the eye.
function project(rig, p) {
  const q = sub(p, rig.eye);
  const depth = dot(q, rig.forward);
  if (!rig.orthographic && depth <= 0) return null;
  const along = rig.orthographic ? 1 : depth;
  const x = dot(q, rig.right) / (along * rig.halfWidth), y = dot(q, rig.up) / (along * rig.halfHeight);
  return { u: (x + 1) / 2, v: (1 - y) / 2 };
}

// ------------------------------------------------------------------ lights: gizmo, marker, fields

const lightIndex = () => Number($("#light").value || 0);
const lightOf = (index) => state.hello.scene.lights[index];

// The selected light's direction from the look-at point (unit, towards the light) and its distance;
// a directional light has only a direction (the way its light travels is the opposite).
function lightPlacement(side = state.editing, index = lightIndex()) {
  const rig = rigOf(side);
  if (lightOf(index).type === "directional") {
    return { toLight: unit(scale(valueIn(side, `lights.${index}.direction`), -1)), distance: null, rig };
  }
  const offset = sub(valueIn(side, `lights.${index}.position`), rig.target);
  const distance = norm(offset);
  return { toLight: distance > 0 ? scale(offset, 1 / distance) : scale(rig.forward, -1), distance, rig };
}

// Move or turn a light in A and (while comparing) B alike, so that the two stay comparable. The gizmo, the
// fields and the marker are redrawn on the next display frame, once however many moves came before it.
function setShared(values, quality) {
  for (const side of state.bStarted ? ["a", "b"] : ["a"]) Object.assign(state.settings[side], values);
  request(quality);
  redrawLight();
}

function placeLight(toLight, distance, quality) {
  const index = lightIndex();
  if (lightOf(index).type === "directional") {
    setShared({ [`lights.${index}.direction`]: rounded(scale(toLight, -1)) }, quality);
  } else {
    setShared({ [`lights.${index}.position`]: rounded(add(rigOf(state.editing).target, scale(toLight, distance))) }, quality);
  }
}

// Trackball: a drag of (dx, dy) pixels turns the light round the camera's up and right axes through
// the look-at point, `perPixel` radians a pixel; relative, so a click never makes it jump.
function turnLight(dx, dy, perPixel, quality) {
  const { toLight, distance, rig } = lightPlacement();
  const turned = rotate(rotate(toLight, rig.up, dx * perPixel), rig.right, dy * perPixel);
  placeLight(unit(turned), distance, quality);
}

// The gizmo shows every direction round the look-at point as a disc (azimuthal equidistant): the centre
// is towards the viewer, the middle ring is the image plane's directions, the rim is straight behind.
function gizmoPoint(rig, toLight, radius) {
  const towardsViewer = scale(rig.forward, -1);
  const angle = Math.acos(Math.max(-1, Math.min(1, dot(toLight, towardsViewer))));
  const x = dot(toLight, rig.right), y = dot(toLight, rig.up);
  const across = Math.hypot(x, y) || 1;
  const r = (radius * angle) / Math.PI;
  return { x: (r * x) / across, y: (-r * y) / across, front: angle <= Math.PI / 2 };
}

function drawGizmo() {
  const canvas = $("#gizmo");
  const g = canvas.getContext("2d");
  const size = canvas.width, radius = size / 2 - 6, centre = size / 2;
  g.clearRect(0, 0, size, size);
  g.fillStyle = "#26282b";
  g.beginPath(); g.arc(centre, centre, radius, 0, 2 * Math.PI); g.fill();
  g.strokeStyle = "#555";
  g.beginPath(); g.arc(centre, centre, radius / 2, 0, 2 * Math.PI); g.stroke();
  g.beginPath(); g.moveTo(centre - radius, centre); g.lineTo(centre + radius, centre);
  g.moveTo(centre, centre - radius); g.lineTo(centre, centre + radius); g.stroke();
  if (!state.hello || !state.hello.scene.lights.length) return;
  state.hello.scene.lights.forEach((_, index) => {
    const { toLight, rig } = lightPlacement(state.editing, index);
    const p = gizmoPoint(rig, toLight, radius);
    const selected = index === lightIndex();
    g.beginPath();
    g.arc(centre + p.x, centre + p.y, selected ? 6 : 4, 0, 2 * Math.PI);
    g.fillStyle = g.strokeStyle = selected ? "#ffd84a" : "#999";
    g.lineWidth = 2;
    if (p.front) g.fill(); else g.stroke();  // hollow: behind the look-at point
    g.lineWidth = 1;
  });
}

// The selected light's marker on each image (hidden when it is off the image or behind the eye).
function drawMarkers() {
  if (!state.hello || !lightOf(lightIndex())) return;
  for (const panel of ["a", "b", "c"]) {
    const marker = $(`#marker-${panel}`);
    const side = panel === "b" && state.compare !== "models" ? "b" : "a";  // the three models are all A's
    const index = lightIndex();
    const at = lightOf(index).type === "point" ? project(rigOf(side), valueIn(side, `lights.${index}.position`)) : null;
    marker.hidden = !at || at.u < 0 || at.u > 1 || at.v < 0 || at.v > 1;
    if (at) { marker.style.left = `${100 * at.u}%`; marker.style.top = `${100 * at.v}%`; }
  }
}

function refreshLight() {
  const index = lightIndex();
  const light = lightOf(index);
  $("#light-box").dataset.off = light ? "0" : "1";
  $("#light-box").disabled = !light || !state.connected;
  if (!light) return;
  const point = light.type === "point";
  $("#light-xyz-name").textContent = point ? "position" : "direction";
  const xyz = valueOf(point ? `lights.${index}.position` : `lights.${index}.direction`);
  for (const input of document.querySelectorAll("#light-xyz input")) {
    if (document.activeElement !== input) input.value = Number(xyz[input.dataset.axis].toFixed(4));
  }
  $("#light-distance").disabled = !point;
  $("#attenuation").disabled = !point;
  const { distance } = lightPlacement();
  if (document.activeElement !== $("#light-distance")) $("#light-distance").value = point ? Number(distance.toFixed(4)) : "";
  for (const term of ["diffuse", "specular"]) {
    const rgb = valueOf(`lights.${index}.${term}`);
    const intensity = Math.max(...rgb);
    $(`#light-${term}-colour`).value = toHex(intensity > 0 ? scale(rgb, 1 / intensity) : [1, 1, 1]);
    if (document.activeElement !== $(`#light-${term}-intensity`)) $(`#light-${term}-intensity`).value = Number(intensity.toPrecision(6));
  }
  const attenuation = valueOf(`lights.${index}.attenuation`);
  $("#attenuation").value = typeof attenuation === "string" ? attenuation : "clq";
  $("#attenuation-clq").hidden = typeof attenuation === "string";
  if (typeof attenuation !== "string") {
    for (const input of document.querySelectorAll("#attenuation-clq input")) input.value = attenuation[input.dataset.term];
  }
  drawGizmo();
  drawMarkers();
}

// How much a light's attenuation dims it at distance d: min(1, 1/(c + l·d + q·d²)) as illumination.py has it.
function dimming(attenuation, d) {
  if (attenuation === "none") return 1;
  const [c, l, q] = attenuation === "inverse_square" ? [0, 0, 1] : attenuation;
  return Math.min(1, 1 / (c + l * d + q * d * d));
}

// A new attenuation for the selected point light, its intensities rescaled so that the look-at point gets
// the light it got before: 1/d² alone would turn a scene lit from 7 units away 50 times darker.
function setAttenuation(attenuation) {
  const index = lightIndex();
  const key = `lights.${index}.attenuation`;
  const { distance } = lightPlacement();
  const ratio = dimming(valueOf(key), distance) / dimming(attenuation, distance);
  const values = { [key]: attenuation };
  for (const term of ["diffuse", "specular"]) {
    values[`lights.${index}.${term}`] = valueOf(`lights.${index}.${term}`).map((x) => Number((x * ratio).toPrecision(6)));
  }
  set(values, "full");
  refreshLight();
}

function wireLight() {
  $("#light").addEventListener("change", refreshLight);
  const gizmo = $("#gizmo");
  const radius = gizmo.width / 2 - 6;
  let last = null;
  gizmo.addEventListener("pointerdown", (event) => {
    gizmo.setPointerCapture(event.pointerId);
    last = { x: event.clientX, y: event.clientY };
  });
  gizmo.addEventListener("pointermove", (event) => {
    if (!last || !gizmo.hasPointerCapture(event.pointerId)) return;
    // Across the disc's radius is a quarter turn: the whole sphere of directions is within one drag.
    turnLight(event.clientX - last.x, event.clientY - last.y, Math.PI / 2 / radius, "draft");
    last = { x: event.clientX, y: event.clientY };
  });
  gizmo.addEventListener("pointerup", (event) => {
    if (!last) return;
    gizmo.releasePointerCapture(event.pointerId);
    last = null;
    request("full");
  });
  let settle = null;
  gizmo.addEventListener("wheel", (event) => {
    event.preventDefault();
    const { toLight, distance } = lightPlacement();
    if (distance === null) return;
    // As far as the wheel turned: 10 % a notch, a trackpad's small steps as little as they move; away when scrolled down.
    placeLight(toLight, distance * Math.exp((wheelPixels(event, event.deltaY) / NOTCH) * PER_NOTCH), "draft");
    clearTimeout(settle);
    settle = setTimeout(() => request("full"), 250);
  }, { passive: false });
  gizmo.addEventListener("keydown", (event) => {
    const step = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] }[event.key];
    if (!step) return;
    event.preventDefault();
    turnLight(step[0], step[1], Math.PI / 36, "full");  // 5° a key press
  });
  for (const input of document.querySelectorAll("#light-xyz input")) {
    input.addEventListener("change", () => {
      const index = lightIndex();
      const key = lightOf(index).type === "point" ? `lights.${index}.position` : `lights.${index}.direction`;
      const xyz = [...valueOf(key)];
      xyz[input.dataset.axis] = Number(input.value);
      setShared({ [key]: xyz }, "full");
    });
  }
  $("#light-distance").addEventListener("change", () => {
    const given = $("#light-distance").value, distance = Number(given);
    if (distance > 0 && Number.isFinite(distance)) {
      hideError();
      placeLight(lightPlacement().toLight, distance, "full");
    } else {  // said, not ignored: the field goes back to the light's distance
      showError(`light distance ${JSON.stringify(given)}: give a number greater than 0 (the light's distance from look_at)`);
      const { distance: kept } = lightPlacement();
      $("#light-distance").value = kept === null ? "" : Number(kept.toFixed(4));
    }
  });
  $("#light-reset").addEventListener("click", () => {
    const prefix = `lights.${lightIndex()}.`;
    for (const side of ["a", "b"]) {
      for (const key of Object.keys(state.settings[side])) if (key.startsWith(prefix)) delete state.settings[side][key];
    }
    refreshLight();
    request("full");
  });
  for (const term of ["diffuse", "specular"]) {
    // The colour is the light's hue at full strength; the intensity (its brightest channel) multiplies it,
    // so a picker never clips a bright light and picking the same colour again changes nothing.
    const apply = (quality) => {
      const intensity = Math.max(0, Number($(`#light-${term}-intensity`).value) || 0);
      set({ [`lights.${lightIndex()}.${term}`]: rounded(scale(fromHex($(`#light-${term}-colour`).value), intensity)) }, quality);
    };
    $(`#light-${term}-colour`).addEventListener("input", () => apply("draft"));
    $(`#light-${term}-colour`).addEventListener("change", () => request("full"));
    $(`#light-${term}-intensity`).addEventListener("change", () => apply("full"));
  }
  $("#attenuation").addEventListener("change", () => {
    const choice = $("#attenuation").value;
    setAttenuation(choice === "clq" ? [1, 0, 1] : choice);
  });
  for (const input of document.querySelectorAll("#attenuation-clq input")) {
    input.addEventListener("change", () => {
      const clq = [...document.querySelectorAll("#attenuation-clq input")].map((x) => Math.max(0, Number(x.value) || 0));
      setAttenuation(clq);
    });
  }
}

// ------------------------------------------------------------------ camera: orbit, pan, zoom

const CAMERA_KEYS = ["camera.position", "camera.look_at", "camera.view_height"];

// Orbit round look_at: (dx, dy) pixels turn the eye round the scene's up axis and the camera's right
// axis, `perPixel` radians a pixel, as if the object were turned with the pointer (f3d, three.js).
function orbit(dx, dy, perPixel, quality) { setShared(orbited(dx, dy, perPixel), quality); }
function orbited(dx, dy, perPixel) {
  const rig = rigOf(state.editing);
  const worldUp = unit(valueOf("camera.up"));
  let offset = rotate(sub(rig.eye, rig.target), worldUp, -dx * perPixel);
  const right = unit(cross(scale(offset, -1), worldUp));
  const pitched = rotate(offset, right, -dy * perPixel);
  // Stop a degree short of the poles: looking along `up` leaves the camera without a frame.
  const fromUp = Math.acos(Math.max(-1, Math.min(1, dot(unit(pitched), worldUp))));
  if (fromUp > Math.PI / 180 && fromUp < Math.PI - Math.PI / 180) offset = pitched;
  return { "camera.position": rounded(add(rig.target, offset)) };
}

// Pan: eye and look_at move together in the image plane, so the point under the pointer follows it
// (at the look_at point's depth); `pixels` is the image's height on screen.
function pan(dx, dy, pixels, quality) {
  const rig = rigOf(state.editing);
  const depth = rig.orthographic ? 1 : norm(sub(rig.target, rig.eye));
  const perPixel = (2 * rig.halfHeight * depth) / pixels;
  const shift = add(scale(rig.right, -dx * perPixel), scale(rig.up, dy * perPixel));
  setShared({ "camera.position": rounded(add(rig.eye, shift)), "camera.look_at": rounded(add(rig.target, shift)) },
            quality);
}

// The near limit: how close to look_at the eye may come along the unit `towardsEye` without entering an object.
// The frames name each object's bounding sphere (a little margin added); the eye stops at the outer side of
// every sphere its path to look_at crosses, except one it is inside already (a room seen from within).
function nearLimit(rig, towardsEye) {
  let near = 0;
  for (const [x, y, z, radius] of (state.lastFrame && state.lastFrame.spheres) || []) {
    const centre = [x, y, z], r = 1.05 * radius;
    if (norm(sub(rig.eye, centre)) < radius) continue;
    const b = dot(towardsEye, sub(centre, rig.target));
    const inside = b * b - (dot(sub(rig.target, centre), sub(rig.target, centre)) - r * r);
    if (inside >= 0) near = Math.max(near, b + Math.sqrt(inside));
  }
  return near;
}

// Zoom by `factor` (> 1: away): a perspective eye moves along its view axis (never into an object: nearLimit),
// an orthographic view widens.
function zoomed(factor, side = state.editing) {
  const rig = rigOf(side);
  if (rig.orthographic) {
    return { "camera.view_height": Number((valueIn(side, "camera.view_height") * factor).toPrecision(6)) };
  }
  const offset = sub(rig.eye, rig.target), distance = norm(offset), towardsEye = scale(offset, 1 / distance);
  let wanted = distance * factor;
  if (factor < 1) wanted = Math.max(wanted, Math.min(distance, nearLimit(rig, towardsEye)));
  if (wanted < 1e-3 || Math.abs(wanted - distance) < 1e-9) return null;
  return { "camera.position": rounded(add(rig.target, scale(towardsEye, wanted))) };
}
function zoom(factor, quality) {
  const values = zoomed(factor);
  if (values) setShared(values, quality);
}

// A wheel's movement in CSS pixels, whatever unit it came in (Firefox counts lines, a page key counts pages).
function wheelPixels(event, delta) {
  return delta * ({ 1: 33, 2: $("#stage").clientHeight }[event.deltaMode] ?? 1);
}
const NOTCH = 100;                // pixels of one mouse-wheel notch in Chromium
const PER_NOTCH = Math.log(1.1);  // a notch zooms 10 %; a trackpad's small steps zoom as little as they move

// The camera glides to a new place (a key, a standard view, fit, reset) over GLIDE ms of drafts, then a full
// frame: a jump loses the eye's sense of where it went. Eye and look-at move in a straight line, the distance
// between them eased.
const GLIDE = 240;
let gliding = null;
function glide(values, after = null) {
  const from = {}, to = {};
  for (const key of Object.keys(values)) { from[key] = valueOf(key); to[key] = values[key]; }
  if (gliding) cancelAnimationFrame(gliding);
  const start = performance.now();
  const step = (now) => {
    const t = Math.min(1, (now - start) / GLIDE), eased = t * t * (3 - 2 * t);
    const at = {};
    for (const key of Object.keys(to)) {
      at[key] = Array.isArray(to[key]) ? rounded(to[key].map((x, i) => from[key][i] + (x - from[key][i]) * eased))
        : Number((from[key] + (to[key] - from[key]) * eased).toPrecision(6));
    }
    if (t < 1) { setShared(at, "draft"); gliding = requestAnimationFrame(step); return; }
    gliding = null;
    state.gliding = false;
    if (after) after(); else setShared(to, "full");
  };
  state.gliding = true;  // the tests wait for the glide's end
  gliding = requestAnimationFrame(step);
}

function resetCamera() {
  const scene = Object.fromEntries(CAMERA_KEYS.map((key) => [key, sceneValue(key)]));
  glide(scene, () => {
    for (const side of ["a", "b"]) for (const key of CAMERA_KEYS) delete state.settings[side][key];
    refreshLight();
    request("full");
  });
}

// The sphere round every object of the newest frame (null before the first frame).
function sceneSphere() {
  const spheres = (state.lastFrame && state.lastFrame.spheres) || [];
  if (!spheres.length) return null;
  const low = [0, 1, 2].map((i) => Math.min(...spheres.map((s) => s[i] - s[3])));
  const high = [0, 1, 2].map((i) => Math.max(...spheres.map((s) => s[i] + s[3])));
  const centre = scale(add(low, high), 0.5);
  return { centre, radius: Math.max(...spheres.map((s) => norm(sub(s.slice(0, 3), centre)) + s[3])) };
}

// Where the camera goes to look at the whole scene from `direction` (unit, from look_at towards the eye; the
// current one if not given): look_at at the scene's centre, the eye far enough for the sphere round it to fit
// the narrower side of the image with a 10 % margin (an orthographic view: its height).
function fitted(direction = null) {
  const sphere = sceneSphere();
  if (!sphere) return null;
  const rig = rigOf(state.editing);
  const towardsEye = direction || unit(sub(rig.eye, rig.target));
  const narrower = Math.min(rig.halfHeight, rig.halfWidth);
  const values = { "camera.look_at": rounded(sphere.centre) };
  if (rig.orthographic) {
    values["camera.view_height"] = Number((2.2 * sphere.radius * rig.halfHeight / narrower).toPrecision(6));
    values["camera.position"] = rounded(add(sphere.centre, scale(towardsEye, 3 * sphere.radius)));
  } else {
    const distance = (1.1 * sphere.radius) / Math.sin(Math.atan(narrower));
    values["camera.position"] = rounded(add(sphere.centre, scale(towardsEye, distance)));
  }
  return values;
}

// The standard views, in the scene's own frame: `up` is camera.up; front looks along −Z (the axis least along
// up), side from +X, top from above (tilted a degree: looking straight along up leaves the camera no frame),
// iso from the corner between the three. The scene keeps its distance; look_at stays.
function standardView(name) {
  const rig = rigOf(state.editing);
  const up = unit(valueOf("camera.up"));
  const axis = Math.abs(up[2]) < 0.9 ? [0, 0, 1] : [0, 1, 0];
  const front = unit(sub(axis, scale(up, dot(axis, up))));
  const side = cross(up, front);
  const tilt = Math.PI / 180;
  const direction = { front, side, iso: unit(add(add(front, side), up)),
                      top: add(scale(up, Math.cos(tilt)), scale(front, Math.sin(tilt))) }[name];
  const distance = norm(sub(rig.eye, rig.target));
  return { "camera.position": rounded(add(rig.target, scale(direction, distance))) };
}

// Turntable: the eye turns round look_at about the scene's up axis, 30° a second, in drafts; a full frame when
// it stops. Any drag or key stops it.
const TURN_PER_SECOND = Math.PI / 6;
let turning = null;
function turntable(on) {
  $("#turntable").checked = on;
  if (turning) cancelAnimationFrame(turning);
  turning = null;
  if (!on) { request("full"); return; }
  let last = performance.now();
  const step = (now) => {
    const angle = TURN_PER_SECOND * (now - last) / 1000;
    last = now;
    const rig = rigOf(state.editing);
    setShared({ "camera.position": rounded(add(rig.target, rotate(sub(rig.eye, rig.target), unit(valueOf("camera.up")), angle))) }, "draft");
    turning = requestAnimationFrame(step);
  };
  turning = requestAnimationFrame(step);
}
const stopTurntable = () => { if (turning) turntable(false); };
const VIEW_KEYS = { 1: "front", 3: "side", 7: "top", 9: "iso", i: "iso" };  // f3d's and Blender's digits

function wireCamera() {
  let last = null, settle = null;
  const touches = new Map();  // the pointers down on the image: two on a touch screen pan and pinch
  const later = () => { clearTimeout(settle); settle = setTimeout(() => request("full"), 250); };
  for (const img of [$("#image-a"), $("#image-b"), $("#image-c")]) {
    img.addEventListener("contextmenu", (event) => event.preventDefault());  // the right button pans
    img.addEventListener("pointerdown", (event) => {
      stopTurntable();
      img.setPointerCapture(event.pointerId);
      touches.set(event.pointerId, { x: event.clientX, y: event.clientY });
      last = { x: event.clientX, y: event.clientY, pan: event.shiftKey || event.button !== 0 };
      $("#stage").focus({ preventScroll: true });
    });
    img.addEventListener("pointermove", (event) => {
      if (!last || !img.hasPointerCapture(event.pointerId)) return;
      if (touches.size === 2) {  // two fingers on a touch screen: pan with their middle, pinch to zoom
        const before = [...touches.values()];
        touches.set(event.pointerId, { x: event.clientX, y: event.clientY });
        const after = [...touches.values()];
        const middle = (p) => ({ x: (p[0].x + p[1].x) / 2, y: (p[0].y + p[1].y) / 2 });
        const spread = (p) => Math.hypot(p[0].x - p[1].x, p[0].y - p[1].y) || 1;
        const [m0, m1] = [middle(before), middle(after)];
        pan(m1.x - m0.x, m1.y - m0.y, img.getBoundingClientRect().height, "draft");
        zoom(spread(before) / spread(after), "draft");
        return;
      }
      touches.set(event.pointerId, { x: event.clientX, y: event.clientY });
      const dx = event.clientX - last.x, dy = event.clientY - last.y;
      const pixels = img.getBoundingClientRect().height;
      // Dragging across the image's height is half a turn.
      if (last.pan) pan(dx, dy, pixels, "draft"); else orbit(dx, dy, Math.PI / pixels, "draft");
      Object.assign(last, { x: event.clientX, y: event.clientY });
    });
    const lift = (event) => {
      touches.delete(event.pointerId);
      if (!last) return;
      img.releasePointerCapture(event.pointerId);
      if (touches.size) { const [p] = touches.values(); Object.assign(last, p); return; }  // one finger stays
      last = null;
      request("full");
    };
    img.addEventListener("pointerup", lift);
    img.addEventListener("pointercancel", lift);
    // The wheel zooms in proportion to how far it turned (a trackpad's small steps, a notch's 10 %); a pinch
    // (a wheel with ctrlKey, as browsers report it) zooms as the fingers spread; two fingers moving mostly
    // sideways on a trackpad, or Shift with the wheel, pan. By the dominant axis: a trackpad's vertical scroll
    // jitters a pixel or two sideways, which must not turn a zoom into a pan.
    img.addEventListener("wheel", (event) => {
      event.preventDefault();
      const dx = wheelPixels(event, event.deltaX), dy = wheelPixels(event, event.deltaY);
      if (event.ctrlKey) zoom(Math.exp(dy / NOTCH), "draft");
      else if (event.shiftKey || Math.abs(dx) > Math.abs(dy)) pan(-(event.shiftKey ? dx || dy : dx), event.shiftKey ? 0 : -dy, img.getBoundingClientRect().height, "draft");
      else zoom(Math.exp((dy / NOTCH) * PER_NOTCH), "draft");  // scrolling down moves away
      later();
    }, { passive: false });
  }
  $("#stage").addEventListener("keydown", (event) => {
    if (!state.connected || event.ctrlKey || event.metaKey || event.altKey) return;  // the browser's own keys
    const arrow = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] }[event.key];
    const pixels = $("#image-a").getBoundingClientRect().height;
    const key = event.key.length === 1 ? event.key.toLowerCase() : event.key;
    const other = { t: () => turntable(!turning), p: () => pixelPeeping(!$("#pixels").checked), c: capture }[key];
    const move = arrow && event.shiftKey ? () => pan(arrow[0] * pixels / 20, arrow[1] * pixels / 20, pixels, "full")  // 5 %
      : arrow ? () => glide(orbited(arrow[0], arrow[1], Math.PI / 36))  // 5° a press
      : { "+": () => glide(zoomed(1 / 1.1) || {}), "=": () => glide(zoomed(1 / 1.1) || {}),
          "-": () => glide(zoomed(1.1) || {}), r: resetCamera, Home: resetCamera, Enter: resetCamera,
          f: () => glide(fitted() || {}) }[key]
        || (VIEW_KEYS[key] && (() => glide(standardView(VIEW_KEYS[key]))));
    if (!move && !other) return;
    event.preventDefault();
    if (move) { stopTurntable(); move(); } else other();
  });
  $("#camera-reset").addEventListener("click", () => { stopTurntable(); resetCamera(); });
  $("#camera-fit").addEventListener("click", () => { stopTurntable(); glide(fitted() || {}); });
  for (const button of document.querySelectorAll("[data-view]")) {
    button.addEventListener("click", () => { stopTurntable(); glide(standardView(button.dataset.view)); });
  }
  $("#turntable").addEventListener("change", () => turntable($("#turntable").checked));
  $("#pixels").addEventListener("change", () => pixelPeeping($("#pixels").checked));
}

function wire() {
  for (const input of document.querySelectorAll("[data-key]")) {
    const value = () => (input.dataset.kind === "int" ? Number(input.value) : input.value);
    const out = input.parentElement.querySelector("output");
    if (input.type === "range") {
      input.addEventListener("input", () => { out.textContent = input.value; set({ [input.dataset.key]: value() }, "draft"); });
    }
    input.addEventListener("change", () => set({ [input.dataset.key]: value() }, "full"));
  }
  $("#shading").addEventListener("change", () => {
    const mine = state.settings[state.editing];
    const model = $("#shading").value;
    for (const key of shadingKeys()) {
      if (model) mine[key] = model; else delete mine[key];  // "as the scene says": the file's own choices
    }
    request("full");
  });
  const level = $("#level");
  const applyLevel = (quality) => {
    level.nextElementSibling.textContent = level.value;
    state.level[state.editing] = Number(level.value);
    set(state.hello.levels[level.value], quality);
  };
  level.addEventListener("input", () => applyLevel("draft"));
  level.addEventListener("change", () => applyLevel("full"));
  wireLight();
  wireCamera();
  wireExtras();
  $("#material").addEventListener("change", refreshControls);
  for (const input of document.querySelectorAll("[data-coefficient]")) {
    input.addEventListener("input", () => set({ [materialKey(input.dataset.coefficient)]: fromHex(input.value) }, "draft"));
    input.addEventListener("change", () => request("full"));
  }
  const shininess = $("#shininess");
  shininess.addEventListener("input", () => {
    shininess.nextElementSibling.textContent = shininessOf(shininess.value);
    set({ [materialKey("shininess")]: shininessOf(shininess.value) }, "draft");
  });
  shininess.addEventListener("change", () => request("full"));
  $("#compare").addEventListener("change", () => {
    const on = $("#compare").value !== "off";
    if (on && $("#compare").value !== "models" && !state.bStarted) {
      // B starts as A is now, with every object in Gouraud shading: the lecture's contrast.
      state.settings.b = { ...state.settings.a };
      for (const key of shadingKeys()) state.settings.b[key] = "gouraud";
      state.level.b = state.level.a;
      state.bStarted = true;
    }
    state.compare = $("#compare").value;
    layoutCompare();
    if (!on || state.compare === "models") { state.editing = "a"; $("#editing").value = "a"; refreshControls(); }
    request("full");
  });
  $("#note").addEventListener("click", () => { $("#note").hidden = true; });
  $("#editing").addEventListener("change", () => { state.editing = $("#editing").value; refreshControls(); });
  $("#wipe").addEventListener("input", wipe);
  $("#load").addEventListener("change", async () => {
    const file = $("#load").files[0];
    if (!file) return;
    const most = state.hello?.limits.scene_bytes ?? Infinity;
    if (file.size > most) {
      return showError(`${file.name}: ${grouped(file.size)} bytes; a scene file the page opens is at most ${grouped(most)} bytes`);
    }
    send({ type: "load", id: state.nextId++, name: file.name, text: await file.text() });
    $("#load").value = "";  // the same file can be opened again
  });
  for (const button of document.querySelectorAll("[data-save]")) {
    button.addEventListener("click", () => send({ type: "save", id: state.nextId++, what: button.dataset.save,
                                                   side: state.editing, settings: state.settings[state.editing] }));
  }
}

// Pixels 1:1: the frame's pixels as squares, unsmoothed, for pixel peeping; otherwise the browser smooths the
// image to the room it has.
function pixelPeeping(on) {
  $("#pixels").checked = on;
  $("#stage").classList.toggle("pixels", on);
  $("#heat-box").classList.toggle("pixels", on);
}

// Capture: what is on screen, in one click: image A as shown (the full frame's PNG bytes, the very file
// `raycast-phong render` writes for these settings) and the scene TOML that makes it. A draft on screen is not
// kept: the full frame is rendered for the file instead.
function capture() {
  const img = $("#image-a");
  const stem = `${(state.hello.source.split("/").pop() || "scene").replace(/\.[^.]*$/, "")}-view-A`;
  if (img.dataset.quality === "full" && state.urls["image-a"]) {
    const link = Object.assign(document.createElement("a"), { href: state.urls["image-a"], download: `${stem}.png` });
    document.body.append(link);
    link.click();
    link.remove();
  } else {
    send({ type: "save", id: state.nextId++, what: "png", side: "a", settings: state.settings.a });
  }
  send({ type: "save", id: state.nextId++, what: "toml", side: "a", settings: state.settings.a });
}

// Undo: each committed change (a full frame asked for: a release, a key, a field) keeps the state before it;
// Ctrl+Z (or the button) goes back one step, up to UNDO_STEPS.
const UNDO_STEPS = 50;
const undoStack = [];
let committed = null;
const snapshot = () => JSON.stringify({ a: state.settings.a, b: state.settings.b, level: state.level,
                                        compare: state.compare, bStarted: state.bStarted });
function remember() {
  const now = snapshot();
  if (committed !== null && now !== committed) {
    undoStack.push(committed);
    if (undoStack.length > UNDO_STEPS) undoStack.shift();
  }
  committed = now;
  $("#undo").disabled = !undoStack.length;
}
function undo() {
  if (!undoStack.length) return;
  const before = JSON.parse(undoStack.pop());
  Object.assign(state, { settings: { a: before.a, b: before.b }, level: before.level, compare: before.compare,
                         bStarted: before.bStarted });
  committed = snapshot();
  $("#undo").disabled = !undoStack.length;
  layoutCompare();
  refreshControls();
  request("full");
}

function wireExtras() {
  $("#capture").addEventListener("click", capture);
  $("#undo").addEventListener("click", undo);
  $("#help-open").addEventListener("click", () => $("#help").showModal());
  $("#help-close").addEventListener("click", () => $("#help").close());
  document.addEventListener("keydown", (event) => {
    const typing = ["INPUT", "SELECT", "TEXTAREA"].includes(event.target.tagName) && event.target.type !== "range"
      && event.target.type !== "checkbox";
    if (event.key === "?" && !typing) {
      event.preventDefault();
      if ($("#help").open) $("#help").close(); else $("#help").showModal();
    } else if ((event.ctrlKey || event.metaKey) && event.key === "z" && !typing) {
      event.preventDefault();
      undo();
    }
  });
}

function layoutCompare() {
  const on = state.compare !== "off";
  const models = state.compare === "models";
  $("#compare").value = state.compare;
  $("#panel-b").hidden = !on;
  $("#panel-c").hidden = !models;
  $("#heat-box").hidden = !on || models;
  $("#wipe").hidden = state.compare !== "wipe";
  $("#editing-label").hidden = !on || models;
  // The panels say what they show: A and B, or A's three shading models.
  [$("#tag-a").textContent, $("#tag-b").textContent] = models ? ["flat", "Gouraud"] : ["A", "B"];
  $("#exact-label").textContent = models ? "exact error" : "exact error of A";
  if (models) $("#exact").textContent = "(of A alone: choose A only or A | B)";
  $("#stage").classList.toggle("wipe", state.compare === "wipe");
  wipe();
}

// ------------------------------------------------------------------ permalink: the settings in the URL

// The URL's fragment carries the settings (A, B, the comparison, the tessellation levels): never sent to the
// server, kept by a reload, the history and a bookmark. It carries no access: the link opens for whoever has the
// server's cookie (this browser), and asks anyone else for the printed URL.
function permalink() {
  const kept = { a: state.settings.a, compare: state.compare, level: state.level };
  if (state.bStarted) kept.b = state.settings.b;
  const fragment = `#view=${encodeURIComponent(JSON.stringify(kept))}`;
  history.replaceState(null, "", `${location.pathname}${location.search}${fragment}`);  // framed: its token kept
  $("#permalink").href = `${location.pathname}${fragment}`;
}

function restore() {
  const found = /^#view=(.*)$/.exec(location.hash);
  if (!found) return;
  let kept;
  try {
    kept = JSON.parse(decodeURIComponent(found[1]));
  } catch (error) {
    return showError(`this link's settings could not be read (${error.message}); showing the scene as it is`);
  }
  const table = (x) => (x && typeof x === "object" && !Array.isArray(x) ? x : {});
  state.settings.a = table(kept.a);
  if (kept.b) { state.settings.b = table(kept.b); state.bStarted = true; }
  state.level = { a: null, b: null, ...table(kept.level) };
  const known = kept.compare === "models" || (["side", "wipe"].includes(kept.compare) && state.bStarted);
  state.compare = known ? kept.compare : "off";
  layoutCompare();
}

function wipe() {
  const share = Number($("#wipe").value);
  for (const id of ["#image-b", "#canvas-b"]) $(id).style.clipPath = state.compare === "wipe" ? `inset(0 0 0 ${share}%)` : "";
  $("#wipe-line").hidden = state.compare !== "wipe";
  $("#wipe-line").style.left = `${share}%`;
}

// The heat map is shown at the size of one image, whatever the layout.
new ResizeObserver(() => { $("#heat").style.width = `${$("#image-a").clientWidth}px`; }).observe($("#image-a"));

wire();
restore();
connected(false, "connecting…");
$("#lost").hidden = true;  // not lost: not yet connected
connect();
