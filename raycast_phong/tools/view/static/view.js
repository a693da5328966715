// raycast-phong view: controls → {dotted scene key: value} over the socket; frames back as PNG.
// The server validates every value with the scene schema and renders; this page only shows what it gets.
"use strict";

const token = new URLSearchParams(location.search).get("token") || "";
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
  sentAt: {},      // request id → time sent, for the change → image latency
  urls: {},        // object URLs on screen, revoked when replaced
  lastFrame: null, // header of the frame on screen (tests read it)
};
window.view = state;  // for the browser tests and the screenshot script

// ------------------------------------------------------------------ socket

const socket = new WebSocket(`ws://${location.host}/socket?token=${encodeURIComponent(token)}`);
socket.binaryType = "arraybuffer";
socket.onopen = () => { $("#connection").textContent = "connected"; };
socket.onclose = (event) => {
  $("#connection").textContent = `disconnected (${event.code})`;
  if (event.code === 1008) showError("the server refused this page: open the URL the view command printed");
};
socket.onmessage = (event) => {
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
  if (header.type === "frame") onFrame(header, parts);
  else if (header.type === "saved") download(header.filename, parts.file);
};

function onText(message) {
  if (message.type === "hello") return onHello(message);
  if (message.type === "error") {
    if (message.id === null || message.id >= state.shownId) showError(message.message);
  } else if (message.type === "errors" && message.id === state.shownId) {
    const pct = (x) => (x === null ? "–" : `${(100 * x).toFixed(1)} %`);
    const num = (x) => (x === null ? "–" : x.toFixed(4));
    $("#exact").textContent = `RMSE ${num(message.rmse)}, max ${num(message.max_error)}, ` +
      `highlight loss ${pct(message.highlight_loss)} (reference ${(1000 * message.seconds).toFixed(0)} ms)`;
  }
}

function send(message) {
  if (socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
}

function request(quality, drag) {
  const id = state.nextId++;
  state.sentAt[id] = performance.now();
  send({
    type: "render", id, quality, drag,
    settings: state.settings.a,
    compare: state.compare === "off" ? null : state.settings.b,
    reference: Boolean(state.hello && state.hello.analytic) && quality === "full",
  });
  return id;
}
state.request = request;

// ------------------------------------------------------------------ frames

function show(img, bytes) {
  const url = URL.createObjectURL(new Blob([bytes], { type: "image/png" }));
  if (state.urls[img.id]) URL.revokeObjectURL(state.urls[img.id]);
  state.urls[img.id] = url;
  img.src = url;
}

function onFrame(header, parts) {
  if (header.id < state.shownId) return;
  state.shownId = header.id;
  // A draft frame (half size) is shown at the full frame's size; side by side, each gets half the room.
  const displayWidth = state.hello.scene.render.width;
  const stageWidth = `${state.compare === "side" ? 2 * displayWidth + 8 : displayWidth}px`;
  $("#stage").style.maxWidth = stageWidth;
  $("#wipe").style.maxWidth = stageWidth;
  for (const name of ["a", "b"]) {
    if (!parts[name]) continue;
    const img = $(`#image-${name}`);
    show(img, parts[name]);
    img.dataset.id = header.id;
    img.dataset.quality = header.quality;
  }
  if (parts.heat) {
    show($("#heat"), parts.heat);
    $("#heat-caption").textContent = `|A − B|, max over RGB: black 0, pale yellow ${header.difference.max.toPrecision(3)}` +
      ` (mean ${header.difference.mean.toPrecision(3)})`;
  } else if (header.difference) {
    $("#heat-caption").textContent = header.difference.note || "";
  }
  for (const [key, value] of Object.entries(header.moved || {})) {
    state.settings.a[key] = value;
    state.settings.b[key] = value;
  }
  const a = header.stats.a;
  $("#frame-time").textContent = `${(1000 * a.frame).toFixed(1)} ms render of ${a.width}×${a.height}` +
    ` (${header.quality}), ${(1000 * header.seconds).toFixed(1)} ms in all`;
  $("#rays").textContent = `${(a.rays_per_second / 1e6).toFixed(1)} M (${a.rays.toLocaleString()} rays, ` +
    `${a.triangles.toLocaleString()} triangles)`;
  const sent = state.sentAt[header.id];
  if (sent !== undefined) $("#latency").textContent = `${(performance.now() - sent).toFixed(0)} ms`;
  for (const id of Object.keys(state.sentAt)) if (Number(id) <= header.id) delete state.sentAt[id];
  $("#left-out").textContent = a.left_out.map((s) => s.name).join(", ") || "nothing";
  $("#left-out").title = a.left_out.map((s) => `${s.name}: ${s.reason}`).join("\n");
  $("#warnings").replaceChildren(...a.warnings.map((w) => Object.assign(document.createElement("li"), { textContent: w })));
  if (header.quality === "draft") $("#exact").textContent = "(when the pointer rests)";
  state.lastFrame = header;
  hideError();
}

function showError(message) {
  $("#error").textContent = message;
  $("#error").hidden = false;
}
function hideError() { $("#error").hidden = true; }

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
function valueOf(key) {
  const mine = state.settings[state.editing];
  return key in mine ? mine[key] : sceneValue(key);
}
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
  const scene = state.hello.scene;
  for (const input of document.querySelectorAll("[data-key]")) {
    input.value = valueOf(input.dataset.key);
    const out = input.parentElement.querySelector("output");
    if (out) out.textContent = input.value;
  }
  $("#shading").value = state.settings[state.editing]["render.shading"] ? valueOf("render.shading") : "";
  const level = state.level[state.editing];
  $("#level").value = level ?? 2;
  $("#level").nextElementSibling.textContent = level ?? "scene";
  const light = scene.lights[0];
  $("#light-box").disabled = !light || light.type !== "point";
  if (light) {
    $("#light-colour").value = toHex(valueOf("lights.0.diffuse"));
    const attenuation = valueOf("lights.0.attenuation");
    $("#attenuation").value = typeof attenuation === "string" ? attenuation : "none";
  }
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
  state.hello = message;
  $("#source").textContent = message.source;
  $("#material").replaceChildren(...message.materials.map((name) => new Option(name, name)));
  refreshControls();
  request("full");
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
  $("#light-colour").addEventListener("input", () => {
    const rgb = fromHex($("#light-colour").value);
    set({ "lights.0.diffuse": rgb, "lights.0.specular": rgb }, "draft");
  });
  $("#light-colour").addEventListener("change", () => request("full"));
  $("#attenuation").addEventListener("change", () => set({ "lights.0.attenuation": $("#attenuation").value }, "full"));
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
    if (on && state.compare === "off" && !state.bStarted) {
      // B starts as A is now, with every object in Gouraud shading: the lecture's contrast.
      state.settings.b = { ...state.settings.a };
      for (const key of shadingKeys()) state.settings.b[key] = "gouraud";
      state.level.b = state.level.a;
      state.bStarted = true;
    }
    state.compare = $("#compare").value;
    $("#panel-b").hidden = !on;
    $("#heat-box").hidden = !on;
    $("#wipe").hidden = state.compare !== "wipe";
    $("#editing-label").hidden = !on;
    $("#stage").classList.toggle("wipe", state.compare === "wipe");
    if (!on) { state.editing = "a"; $("#editing").value = "a"; refreshControls(); }
    wipe();
    request("full");
  });
  $("#editing").addEventListener("change", () => { state.editing = $("#editing").value; refreshControls(); });
  $("#wipe").addEventListener("input", wipe);
  for (const button of document.querySelectorAll("[data-save]")) {
    button.addEventListener("click", () => send({ type: "save", id: state.nextId++, what: button.dataset.save,
                                                   settings: state.settings[state.editing] }));
  }
  // Drag the first light: the server maps the pointer to a point on a plane in front of the camera.
  for (const img of [$("#image-a"), $("#image-b")]) {
    const at = (event) => {
      const box = img.getBoundingClientRect();
      return { light: 0, u: (event.clientX - box.left) / box.width, v: (event.clientY - box.top) / box.height };
    };
    img.addEventListener("pointerdown", (event) => {
      if ($("#light-box").disabled) return;
      img.setPointerCapture(event.pointerId);
      request("draft", at(event));
    });
    img.addEventListener("pointermove", (event) => {
      if (img.hasPointerCapture(event.pointerId)) request("draft", at(event));
    });
    img.addEventListener("pointerup", (event) => {
      if (!img.hasPointerCapture(event.pointerId)) return;
      img.releasePointerCapture(event.pointerId);
      request("full", at(event));
    });
  }
}

function wipe() {
  const share = Number($("#wipe").value);
  $("#image-b").style.clipPath = state.compare === "wipe" ? `inset(0 0 0 ${share}%)` : "";
  $("#wipe-line").hidden = state.compare !== "wipe";
  $("#wipe-line").style.left = `${share}%`;
}

// The heat map is shown at the size of one image, whatever the layout.
new ResizeObserver(() => { $("#heat").style.width = `${$("#image-a").clientWidth}px`; }).observe($("#image-a"));

wire();
