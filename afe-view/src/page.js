"use strict";
// afe live view: one WebSocket; text messages describe the graph, binary ones carry
// batches of frames (see afe-view/src/lib.rs for the protocol).
const $ = (id) => document.getElementById(id);
const COLUMNS = 600;                 // frames (or blocks) across a scrolling canvas
const ABOVE = 240;                   // pixels across a view from above
const state = { hello: null, layout: null, panels: new Map(), stats: { frames: 0, lost: 0, batches: 0, lagged: 0 } };
window.afeStats = state.stats;

// Colour maps: a perceptual sequential one (viridis-like) and a blue-white-red one.
function sequential(t) {
  t = Math.min(1, Math.max(0, t));
  const r = 0.267 + t * (0.004 + t * (1.4 - t * 0.67));
  const g = 0.005 + t * (1.3 - t * 0.4);
  const b = 0.33 + t * (1.2 - t * (2.3 - t * 0.9));
  return [255 * Math.min(1, Math.max(0, r)), 255 * Math.min(1, g), 255 * Math.min(1, Math.max(0, b))];
}
function diverging(t) {       // t in [-1, 1]
  t = Math.min(1, Math.max(-1, t));
  return t < 0 ? [255 * (1 + t), 255 * (1 + t), 255] : [255, 255 * (1 - t), 255 * (1 - t)];
}

function fmt(v) {
  const a = Math.abs(v);
  if (a === 0) return "0";
  if (a >= 1000) return (v / 1000).toFixed(1) + "k";
  if (a >= 10) return v.toFixed(0);
  if (a >= 0.01) return v.toPrecision(2);
  return v.toExponential(0);
}

function send(msg) {
  if (state.ws && state.ws.readyState === 1) state.ws.send(JSON.stringify(msg));
}

function log(text, bad) {
  const el = $("log");
  el.textContent = text;
  el.className = bad ? "bad" : "";
}

// A panel per signal, drawn as its description's plan says (never by its name): one
// frame as an image, a line, an envelope of a waveform, or columns scrolling over time.
class Panel {
  constructor(key, d) {
    this.key = key;
    this.d = d;
    const shape = d.frame_shape;
    const plan = d.plan;
    this.plan = plan;
    this.mode = plan.panel === "frame" ? "frame" : plan.panel === "line" ? "line"
      : plan.panel === "from-above" ? "above"
      : plan.panel === "waveforms" && !plan.rows ? "envelope" : "scroll";
    // signed values on a diverging map; decibel scales (10·log10 of a power, 20·log10
    // of a magnitude) over their range below the running peak
    this.diverging = plan.scale.scale === "signed";
    this.range = plan.scale.range_db || 0;
    this.decibels = plan.scale.scale === "power-decibels" ? 10 : 20;
    this.rows = shape.length === 0 ? 1 : shape[0];
    this.cols = shape.length >= 2 ? shape.slice(1).reduce((a, b) => a * b, 1) : COLUMNS;
    this.max = 1e-12;
    this.min = Infinity;
    this.pending = [];            // envelope: samples not yet making a column
    this.el = document.createElement("div");
    this.el.className = "panel";
    this.el.id = "panel-" + key;
    const what = [d.kind, plan.values || "", d.hop_s ? `hop ${d.hop_s * 1000} ms` : `${d.fs_hz} Hz`]
      .filter(Boolean).join(", ");
    this.el.innerHTML = `<h2>${key} <span class="meta">${what}</span><button>remove</button></h2>
      <div class="plot"><div class="axis"></div><canvas class="data"></canvas>
      <div class="bar"><canvas width="1" height="64"></canvas><div><span></span><span></span></div></div></div>`;
    this.canvas = this.el.querySelector("canvas.data");
    this.canvas.width = this.mode === "frame" ? this.cols : this.mode === "above" ? ABOVE : COLUMNS;
    this.canvas.height = this.mode === "line" ? 150 : this.mode === "above" ? ABOVE : this.rows;
    if (this.mode === "above") {
      // a square seen from above, no colour bar
      this.canvas.style.flex = "none";
      this.canvas.style.width = "150px";
      this.canvas.style.imageRendering = "auto";
      this.el.querySelector(".bar").style.display = "none";
    }
    this.ctx = this.canvas.getContext("2d");
    this.ctx.fillStyle = "#000";
    this.ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    this.el.querySelector("button").onclick = () => this.remove();
    this.drawAxis();
    this.drawBar();
  }

  remove() {
    const req = (state.layout.requests || []).find((r) => r.outputs.includes(this.key));
    if (req) send({ op: "remove", handle: req.handle });
  }

  // The rows' axis: a few of its ticks with its unit, or its title where it has few.
  drawAxis() {
    const axis = this.el.querySelector(".axis");
    const rows = this.plan.rows;
    if (this.mode === "line") {
      axis.innerHTML = `<span style="top:2%">${this.plan.values}</span>`;
      return;
    }
    if (this.mode === "above") {
      axis.innerHTML = `<span style="top:50%">from above</span>`;
      return;
    }
    if (!rows) {
      axis.innerHTML = "";
      return;
    }
    axis.title = rows.label;
    const ticks = rows.ticks;
    if (ticks.length < 2 || this.mode === "frame") {
      axis.innerHTML = `<span style="top:50%">${rows.label}</span>`;
      return;
    }
    const unit = (rows.label.match(/\(([^)]*)\)$/) || ["", ""])[1];
    const picks = [0, Math.floor(ticks.length / 3), Math.floor((2 * ticks.length) / 3), ticks.length - 1];
    axis.innerHTML = picks.map((c) => {
      const top = 100 * (1 - (c + 0.5) / ticks.length);
      return `<span style="top:${top}%">${ticks[c]} ${unit}</span>`;
    }).join("");
  }

  drawBar() {
    const bar = this.el.querySelector(".bar canvas");
    const ctx = bar.getContext("2d");
    for (let y = 0; y < 64; y++) {
      const t = 1 - y / 63;
      const [r, g, b] = this.diverging ? diverging(2 * t - 1) : sequential(t);
      ctx.fillStyle = `rgb(${r | 0},${g | 0},${b | 0})`;
      ctx.fillRect(0, y, 1, 1);
    }
    const labels = this.el.querySelectorAll(".bar span");
    const unit = this.range ? "dB" : this.plan.values || "";
    const lo = this.diverging ? -this.max : this.min === Infinity ? 0 : this.min;
    labels[0].textContent = `${fmt(this.max)} ${unit}`;
    labels[1].textContent = `${fmt(lo)} ${unit}`;
  }

  colour(v) {
    if (this.diverging) return diverging(v / this.max);
    const lo = this.min === Infinity ? 0 : this.min;
    return sequential((v - lo) / Math.max(1e-12, this.max - lo));
  }

  value(v) {
    return this.range ? this.decibels * Math.log10(Math.max(Math.abs(v), 1e-10)) : v;
  }

  // Scales follow the data: they widen and never narrow, so that earlier columns keep
  // their meaning (a dB range follows its peak).
  rescale(values) {
    let hi = -Infinity, lo = Infinity;
    for (const x of values) {
      const v = this.value(x);
      if (!Number.isFinite(v)) continue;
      hi = Math.max(hi, this.diverging ? Math.abs(v) : v);
      lo = Math.min(lo, v);
    }
    if (hi === -Infinity) return;
    const before = [this.min, this.max];
    if (this.range) {
      this.max = this.max === 1e-12 ? hi : Math.max(hi, this.max);
      this.min = this.max - this.range;
    } else if (this.plan.scale.scale === "mask") {
      this.min = 0; this.max = 1;
    } else {
      this.max = Math.max(hi, this.max);
      this.min = Math.min(lo, this.min);
    }
    if (before[0] !== this.min || before[1] !== this.max) this.drawBar();
  }

  // Scrolls the canvas by `n` columns and returns the image of the new columns.
  scroll(n) {
    const w = this.canvas.width, h = this.canvas.height;
    n = Math.min(n, w);
    this.ctx.drawImage(this.canvas, n, 0, w - n, h, 0, 0, w - n, h);
    return this.ctx.createImageData(n, h);
  }

  putColumn(img, x, column) {
    const h = this.canvas.height;
    for (let c = 0; c < column.length; c++) {
      const [r, g, b] = this.colour(this.value(column[c]));
      const i = 4 * ((h - 1 - c) * img.width + x);
      img.data[i] = r; img.data[i + 1] = g; img.data[i + 2] = b; img.data[i + 3] = 255;
    }
  }

  draw(values, rows) {
    if (rows === 0) return;
    // frames drawn so far, on the panel's element (a test reads it from the DOM)
    this.el.dataset.drawn = (+this.el.dataset.drawn || 0) + rows;
    const width = values.length / rows;
    if (this.mode === "above") {
      this.drawAbove(values.subarray((rows - 1) * width));
      return;
    }
    this.rescale(values);
    if (this.mode === "frame") {
      // the latest frame: channels up, lags (or modulation channels, bins) across
      const last = values.subarray((rows - 1) * width);
      const img = this.ctx.createImageData(this.cols, this.rows);
      for (let c = 0; c < this.rows; c++) {
        for (let x = 0; x < this.cols; x++) {
          const [r, g, b] = this.colour(this.value(last[c * this.cols + x]));
          const i = 4 * ((this.rows - 1 - c) * this.cols + x);
          img.data[i] = r; img.data[i + 1] = g; img.data[i + 2] = b; img.data[i + 3] = 255;
        }
      }
      this.ctx.putImageData(img, 0, 0);
      return;
    }
    if (this.mode === "line") {
      const w = this.canvas.width, h = this.canvas.height;
      const n = Math.min(rows, w);
      this.ctx.drawImage(this.canvas, n, 0, w - n, h, 0, 0, w - n, h);
      this.ctx.fillStyle = "#000";
      this.ctx.fillRect(w - n, 0, n, h);
      this.ctx.fillStyle = "#7fd";
      for (let k = rows - n; k < rows; k++) {
        const v = values[k * width];
        if (!Number.isFinite(v)) continue;           // NaN (no value in this frame): a gap
        const y = h - 1 - (h - 2) * Math.min(1, v / Math.max(this.max, 1));
        this.ctx.fillRect(w - n + (k - rows + n), y - 1, 1, 3);
      }
      return;
    }
    if (this.mode === "envelope") {
      // full-rate signals: one column per 10 ms, the largest magnitude of each channel
      const per = Math.max(1, Math.round(this.d.fs_hz / 100));
      for (let k = 0; k < rows; k++) this.pending.push(values.subarray(k * width, (k + 1) * width));
      const columns = Math.floor(this.pending.length / per);
      if (columns === 0) return;
      const img = this.scroll(columns);
      for (let x = 0; x < columns; x++) {
        const col = new Float32Array(width);
        for (let k = x * per; k < (x + 1) * per; k++) {
          const row = this.pending[k];
          for (let c = 0; c < width; c++) col[c] = Math.max(col[c], Math.abs(row[c]));
        }
        this.putColumn(img, x, col);
      }
      this.pending = this.pending.slice(columns * per);
      this.ctx.putImageData(img, this.canvas.width - columns, 0);
      return;
    }
    const n = Math.min(rows, this.canvas.width);
    const img = this.scroll(n);
    for (let k = rows - n, x = 0; k < rows; k++, x++) {
      this.putColumn(img, x, values.subarray(k * width, (k + 1) * width));
    }
    this.ctx.putImageData(img, this.canvas.width - n, 0);
  }
}

// Sources tracked about the head, seen from above (the plan's from_above says where a
// frame holds them): the head turned by its yaw, each source on the ring at its world
// azimuth (0 up, 90 to the left) with an arc of its uncertainty, filled once front is told
// from back, and the suggested turn dashed; the same in words as the canvas's title.
Panel.prototype.drawAbove = function (frame) {
  const sc = this.plan.from_above, ctx = this.ctx;
  const c = ABOVE / 2, ring = 0.4 * ABOVE;
  const at = (deg, r) => {
    const a = (deg * Math.PI) / 180;
    return [c - r * Math.sin(a), c - r * Math.cos(a)];
  };
  const angle = (deg) => -(Math.PI / 2 + (deg * Math.PI) / 180);
  ctx.fillStyle = "#000";
  ctx.fillRect(0, 0, ABOVE, ABOVE);
  ctx.strokeStyle = "#334";
  ctx.lineWidth = 1;
  ctx.beginPath(); ctx.arc(c, c, ring, 0, 2 * Math.PI); ctx.stroke();
  const yaw = frame[sc.head_yaw], target = frame[sc.suggested_yaw];
  ctx.fillStyle = "#556";
  ctx.beginPath(); ctx.arc(c, c, 0.08 * ABOVE, 0, 2 * Math.PI); ctx.fill();
  ctx.strokeStyle = "#fa4";
  ctx.lineWidth = 3;
  ctx.beginPath(); ctx.moveTo(c, c); ctx.lineTo(...at(yaw, 0.16 * ABOVE)); ctx.stroke();
  const words = [`head ${fmt(yaw)}°`];
  if (Number.isFinite(target)) {
    ctx.strokeStyle = "#ee5";
    ctx.lineWidth = 1;
    ctx.setLineDash([4, 3]);
    ctx.beginPath(); ctx.moveTo(c, c); ctx.lineTo(...at(target, 0.3 * ABOVE)); ctx.stroke();
    ctx.setLineDash([]);
    words.push(`turn to ${fmt(target)}°`);
  }
  let sources = 0;
  for (let k = 0; k < sc.slots; k++) {
    const slot = frame.subarray(k * sc.slot_width, (k + 1) * sc.slot_width);
    const az = slot[sc.azimuth];
    if (!Number.isFinite(az)) continue;
    const id = slot[sc.id], spread = Math.max(2, slot[sc.uncertainty]);
    const hue = (id * 137) % 360;
    ctx.strokeStyle = ctx.fillStyle = `hsl(${hue},80%,60%)`;
    ctx.lineWidth = 4;
    ctx.beginPath(); ctx.arc(c, c, ring, angle(az + spread), angle(az - spread)); ctx.stroke();
    ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(...at(az, ring), 6, 0, 2 * Math.PI);
    if (slot[sc.resolved] === 1) ctx.fill(); else ctx.stroke();
    sources += 1;
    words.push(`#${id} ${fmt(az)}±${fmt(slot[sc.uncertainty])}°${slot[sc.resolved] === 1 ? "" : " (or its mirror)"}`);
  }
  this.canvas.title = words.join(", ");
  this.el.dataset.sources = sources;
};

// The robot the stream comes from, from its platform descriptor: its name, its
// microphones by role and its head model (the whole descriptor as the tooltip).
function showRobot(p) {
  const el = $("robot");
  el.hidden = !p;
  if (!p) return;
  const roles = p.audio.channels.map((c) => c.role).join(", ");
  el.textContent = `${p.robot} · ${p.audio.channels.length} microphones (${roles}) · head ${p.audio.head}`;
  el.title = JSON.stringify(p, null, 1);
}

function onLayout(layout) {
  if (!state.hello) {
    $("request").innerHTML = layout.catalogue.map((r) => `<option>${r}</option>`).join("");
    showRobot(layout.platform);
  }
  state.hello = layout;
  state.layout = layout;
  // a server started without requests: say so until one is added
  $("empty").hidden = layout.order.length > 0;
  const keep = new Set(layout.order);
  for (const [key, p] of state.panels) {
    if (!keep.has(key) || JSON.stringify(p.d.parameters) !== JSON.stringify(layout.signals[key].parameters)) {
      p.el.remove();
      state.panels.delete(key);
    }
  }
  for (const key of layout.order) {
    if (!state.panels.has(key)) {
      const p = new Panel(key, layout.signals[key]);
      state.panels.set(key, p);
      $("panels").appendChild(p.el);
    }
  }
}

const wave = { ctx: null };
function drawWave(values, ears) {
  const canvas = $("wave");
  const ctx = wave.ctx || (wave.ctx = canvas.getContext("2d"));
  const w = canvas.width, h = canvas.height;
  const blocks = values.length / (2 * ears);
  const n = Math.min(blocks, w);
  ctx.drawImage(canvas, n, 0, w - n, h, 0, 0, w - n, h);
  ctx.fillStyle = "#000";
  ctx.fillRect(w - n, 0, n, h);
  const colours = ["rgba(120,200,255,0.8)", "rgba(255,160,120,0.7)"];
  for (let k = blocks - n, x = w - n; k < blocks; k++, x++) {
    for (let e = 0; e < ears; e++) {
      const lo = values[2 * (k * ears + e)], hi = values[2 * (k * ears + e) + 1];
      ctx.fillStyle = colours[e];
      const y0 = h / 2 - (h / 2) * Math.min(1, hi), y1 = h / 2 - (h / 2) * Math.max(-1, lo);
      ctx.fillRect(x, y0, 1, Math.max(1, y1 - y0));
    }
  }
}

const audio = { ctx: null, next: 0 };
function play(samples, ears) {
  if (!$("listen").checked || samples.length === 0) return;
  if (!audio.ctx) audio.ctx = new AudioContext({ sampleRate: state.hello.fs_hz });
  const frames = samples.length / ears;
  const buf = audio.ctx.createBuffer(ears, frames, state.hello.fs_hz);
  for (let e = 0; e < ears; e++) {
    const ch = buf.getChannelData(e);
    for (let t = 0; t < frames; t++) ch[t] = samples[t * ears + e];
  }
  const src = audio.ctx.createBufferSource();
  src.buffer = buf;
  src.connect(audio.ctx.destination);
  audio.next = Math.max(audio.next, audio.ctx.currentTime + 0.15);
  src.start(audio.next);
  audio.next += frames / state.hello.fs_hz;
}

function onFrames(buffer) {
  if (!state.hello) return;          // frames before the first layout: nothing to draw on
  const view = new DataView(buffer);
  const hlen = view.getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, hlen)));
  const start = 4 + hlen + ((4 - ((4 + hlen) % 4)) % 4);
  const values = new Float32Array(buffer, start);
  for (const s of header.signals) {
    const p = state.panels.get(s.key);
    if (p) p.draw(values.subarray(s.offset, s.offset + s.len), s.rows);
  }
  const ears = state.hello.ears;
  drawWave(values.subarray(header.wave.offset, header.wave.offset + header.wave.len), ears);
  play(values.subarray(header.audio.offset, header.audio.offset + header.audio.len), ears);
  const st = state.stats;
  st.batches += 1;
  st.frames = header.frames_total;
  st.lost = header.lost_frames + header.dropped_frames + st.lagged;
  $("frames").textContent = st.frames;
  $("time").textContent = (st.frames / state.hello.fs_hz).toFixed(2);
  $("lost").textContent = st.lost;
  $("lost").className = st.lost > 0 ? "bad" : "";
  $("load").textContent = (100 * header.compute_ms_max / header.budget_ms).toFixed(0);
}

function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = "arraybuffer";
  state.ws = ws;
  let opened = false;
  ws.onopen = () => { opened = true; $("conn").textContent = "live"; };
  ws.onclose = (ev) => {
    // a refusal says why in the close frame; one before opening (an origin the
    // server does not allow) only in the server's log
    const why = ev.reason || (opened ? "" : "refused by the server (its log says why)");
    if ($("conn").textContent !== "stream ended") $("conn").textContent = "disconnected";
    if (why) log(why, ev.code !== 1000);
    $("conn").className = ev.code === 1000 ? "" : "bad";
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data !== "string") { onFrames(ev.data); return; }
    const msg = JSON.parse(ev.data);
    if (msg.type === "layout") {
      onLayout(msg);
    } else if (msg.type === "reply") {
      log(msg.message, !msg.ok);
    } else if (msg.type === "refused") {
      log(msg.message, true);
    } else if (msg.type === "lagged" && state.hello) {
      // this page fell behind: whole batches were skipped for it
      const blockFrames = Math.round(state.hello.block_ms * state.hello.fs_hz / 1000);
      state.stats.lagged += msg.batches * blockFrames * Math.ceil(50 / state.hello.block_ms);
    } else if (msg.type === "end") {
      $("conn").textContent = "stream ended";
    }
  };
}

$("add").onclick = () => send({ op: "add", request: $("request").value });
$("set").onclick = () => {
  let value = $("pvalue").value;
  try { value = JSON.parse(value); } catch (e) { /* a plain string, e.g. hann */ }
  send({ op: "set", name: $("pname").value.trim(), value });
};
$("listen").onchange = () => send({ op: "audio", on: $("listen").checked });
connect();
