// The base station's live view: one websocket (/ws), one canvas, a few tables.
// Messages are described in station/web.py. No library: the page works offline.
"use strict";

const $ = (id) => document.getElementById(id);
const view = {            // also read by the browser test and the load bench
  hello: null, map: null, mapUpdates: 0, trail: [], path: [], last: null, ended: false,
  packets: 0, gaps: 0, lastIndex: -1, drawn: 0, connected: false, end: null,
};
window.stationView = view;
let dirty = false;

function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${proto}://${location.host}/ws`);
  ws.onopen = () => { view.connected = true; setConn(); };
  ws.onclose = () => { view.connected = false; setConn(); setTimeout(connect, 1000); };
  ws.onmessage = (ev) => { handle(JSON.parse(ev.data)); };
}

function handle(m) {
  switch (m.type) {
    case "hello":
      Object.assign(view, { hello: m, map: null, trail: [], path: [], last: null,
                            ended: false, end: null, lastIndex: -1 });
      $("source").textContent = m.source || "";
      break;
    case "trail":
      view.trail = m.trail;
      break;
    case "path":
      view.path = m.path;
      break;
    case "packet":
      if (view.lastIndex >= 0 && m.index !== view.lastIndex + 1) {
        view.gaps += Math.max(0, m.index - view.lastIndex - 1);
      }
      view.lastIndex = m.index;
      if (m.index === view.trail.length) view.trail.push([m.pose[0], m.pose[1]]);
      view.packets += 1;
      view.last = m;
      break;
    case "map": {
      const bin = atob(m.data);
      const q = new Int8Array(bin.length);
      for (let i = 0; i < bin.length; i++) q[i] = (bin.charCodeAt(i) << 24) >> 24;
      view.map = q;
      view.mapUpdates = m.updates;
      break;
    }
    case "end":
      view.ended = true;
      view.end = m;
      break;
  }
  if (!dirty) { dirty = true; requestAnimationFrame(render); }
}

function setConn() {
  const c = $("conn");
  c.textContent = view.connected ? "live" : "disconnected";
  c.className = "badge" + (view.connected ? "" : " off");
}

function fmt(v, d) { return v === null || v === undefined ? "-" : Number(v).toFixed(d); }

function render() {
  dirty = false;
  if (!view.hello) return;
  drawMap();
  const m = view.last;
  const rs = $("runstate");
  rs.textContent = view.ended ? "recording ended" : (m ? "running" : "waiting for packets");
  rs.className = "badge" + (view.ended ? " idle" : "");
  $("view").textContent = `${view.packets} packet messages, ${view.gaps} missed, ` +
    `map after ${view.mapUpdates} updates`;
  if (!m) return;
  const [x, y, th] = m.pose;
  $("pose").innerHTML = `x <span id="pose-x">${x.toFixed(3)}</span> m, ` +
    `y <span id="pose-y">${y.toFixed(3)}</span> m, ` +
    `&theta; <span id="pose-th">${(th * 180 / Math.PI).toFixed(2)}</span>&deg;`;
  $("seq").textContent = `seq ${m.seq} (#${m.index + 1})` + (m.used ? "" : " implausible");
  $("time").textContent = m.t.toFixed(1);
  const hits = m.bands.filter((b) => b > 0).length;
  $("bands").textContent = `${hits}/${m.bands.length} with an obstacle, ` +
    `${m.points.length} points`;
  const p = m.plan;
  $("plan-status").textContent = `${p.status || "-"} (${p.planner})`;
  $("plan-status").className = p.status && p.status !== "ok" ? "bad" : "";
  $("path-cost").textContent = p.length_m === null ? "-" :
    `${fmt(p.length_m, 2)} m (colony ${fmt(p.raw_length_m, 2)} m)`;
  $("replans").textContent = `${p.replans}` + (p.last_reason ? `, last: ${p.last_reason}` : "");
  $("plan-time").textContent = p.last_plan_s === null ? "-" :
    `last ${fmt(p.last_plan_s * 1000, 0)} ms, mean ${fmt(p.plan_s_mean * 1000, 0)}, ` +
    `max ${fmt(p.plan_s_max * 1000, 0)}`;
  const L = view.end ? view.end.link : m.link;
  $("accepted").textContent = L.accepted;
  $("lost").textContent = L.lost;
  $("rejected-total").textContent = L.rejected_total;
  $("rejected").textContent = Object.entries(L.rejected)
    .map(([k, v]) => `${k} ${v}`).join(", ");
  $("misc").textContent = `${L.duplicates} / ${L.garbage_bytes}`;
  $("implausible").textContent = L.implausible;
  health(m.health);
}

function health(h) {
  const flags = [["LEFT_LOCKED", "left camera", "locked", "not locked", true],
                 ["RIGHT_LOCKED", "right camera", "locked", "not locked", true],
                 ["PIPELINE_ENABLED", "pipeline", "on", "off", true],
                 ["HUE_FALLBACK", "hue fallback", "on", "off", false],
                 ["RECT_FAULT", "rectification", "not running", "on", false],
                 ["RADIO_FAULT", "robot's XBee", "not answering", "ok", false],
                 ["DECODER_FAULT", "decoder set-up", "failed", "ok", false],
                 ["CAMERA_LOST", "camera feed", "lost", "ok", false]];
  // a camera lost since the last packet: its badge says so, CAMERA_LOST's names it
  const lost = h.cameras_lost || [];
  let html = "";
  for (const [k, label, yes, no, good] of flags) {
    const on = h.flag_names.includes(k);
    const cls = good ? (on ? "" : " off") : (on ? " warn" : " idle");
    let text = on ? yes : no;
    if (k.endsWith("_LOCKED") && !on && lost.includes(label.split(" ")[0])) {
      text = "lost";
    } else if (k === "CAMERA_LOST" && on && lost.length) {
      text += ` (${lost.join(", ")})`;
    }
    html += `<span class="badge${cls}">${label}: ${text}</span>`;
  }
  $("flags").innerHTML = html;
  const rows = [["frames", h.frames], ["pairs ok", h.pairs_ok],
                ["mispaired (capture skew)", h.mispaired], ["drops", h.drops],
                ["camera errors L / R", h.cam_errors.join(" / ")],
                ["matcher errors", h.matcher_errors], ["FIFO overflows", h.fifo_overflow]];
  $("health").innerHTML = rows.map(([k, v], i) => {
    const bad = i >= 2 && String(v).split(" / ").some((s) => Number(s) > 0);
    return `<tr><th>${k}</th><td${bad ? ' class="bad"' : ""}>${v}</td></tr>`;
  }).join("");
}

function drawMap() {
  const g = view.hello.grid;
  const cv = $("map");
  const scale = Math.max(1, Math.floor(Math.min(720 / g.nx, 480 / g.ny)));
  if (cv.width !== g.nx * scale) { cv.width = g.nx * scale; cv.height = g.ny * scale; }
  const ctx = cv.getContext("2d");
  const H = cv.height;
  const X = (x) => (x - g.x_min) / g.res * scale;
  const Y = (y) => H - (y - g.y_min) / g.res * scale;
  if (view.map && view.map.length === g.nx * g.ny) {
    const img = new ImageData(g.nx, g.ny);
    const occ = g.l_occ * 20;
    for (let r = 0; r < g.ny; r++) {
      for (let c = 0; c < g.nx; c++) {
        const q = view.map[r * g.nx + c];
        const o = ((g.ny - 1 - r) * g.nx + c) * 4;   // row 0 is y_min: the bottom
        let v;
        if (q > occ) v = 20;
        else if (q >= 0) v = 140 - q * 1.5;
        else v = Math.min(242, 140 - q * 2.6);
        img.data[o] = img.data[o + 1] = img.data[o + 2] = v;
        img.data[o + 3] = 255;
      }
    }
    const off = new OffscreenCanvas(g.nx, g.ny);
    off.getContext("2d").putImageData(img, 0, 0);
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(off, 0, 0, cv.width, cv.height);
    view.drawn += 1;
    cv.dataset.drawn = String(view.drawn);
  } else {
    ctx.fillStyle = "#8c8c8c";
    ctx.fillRect(0, 0, cv.width, cv.height);
  }
  // metre grid
  ctx.strokeStyle = "rgba(255,255,255,0.15)";
  ctx.lineWidth = 1;
  for (let x = Math.ceil(g.x_min); x <= g.x_min + g.nx * g.res; x++) {
    ctx.beginPath(); ctx.moveTo(X(x), 0); ctx.lineTo(X(x), H); ctx.stroke();
  }
  for (let y = Math.ceil(g.y_min); y <= g.y_min + g.ny * g.res; y++) {
    ctx.beginPath(); ctx.moveTo(0, Y(y)); ctx.lineTo(cv.width, Y(y)); ctx.stroke();
  }
  ctx.fillStyle = "rgba(255,255,255,0.7)";
  ctx.font = "11px sans-serif";
  for (let x = Math.ceil(g.x_min); x < g.x_min + g.nx * g.res; x++) {
    ctx.fillText(`x ${x} m`, X(x) + 3, H - 4);
  }
  for (let y = Math.ceil(g.y_min); y < g.y_min + g.ny * g.res; y++) {
    ctx.fillText(`y ${y} m`, 3, Y(y) - 3);
  }
  const m = view.last;
  if (m) {   // free-space bands of the last packet
    const [ox, oy] = m.origin;
    for (const [lo, hi, reach, kind] of m.free) {
      if (kind === "none") continue;
      ctx.fillStyle = kind === "hit" ? "rgba(40,190,80,0.30)" : "rgba(40,190,80,0.15)";
      ctx.beginPath();
      ctx.moveTo(X(ox), Y(oy));
      ctx.lineTo(X(ox + reach * Math.cos(lo)), Y(oy + reach * Math.sin(lo)));
      ctx.lineTo(X(ox + reach * Math.cos(hi)), Y(oy + reach * Math.sin(hi)));
      ctx.closePath();
      ctx.fill();
    }
  }
  line(ctx, view.trail, X, Y, "#2f6fdd", 2);
  line(ctx, view.path, X, Y, "#ff8c1a", 3);
  const [gx, gy] = view.hello.goal;
  ctx.strokeStyle = "#19a34a"; ctx.lineWidth = 3;
  ctx.beginPath(); ctx.arc(X(gx), Y(gy), 8, 0, 2 * Math.PI); ctx.stroke();
  if (m) {
    ctx.fillStyle = "#e0262b";
    for (const [px, py] of m.points) {
      ctx.beginPath(); ctx.arc(X(px), Y(py), 3, 0, 2 * Math.PI); ctx.fill();
    }
    const [x, y, th] = m.pose;
    const s = Math.max(6, 0.1 / g.res * scale);
    ctx.save();
    ctx.translate(X(x), Y(y));
    ctx.rotate(-th);
    ctx.fillStyle = "#7b2fbf"; ctx.strokeStyle = "#fff"; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.moveTo(s * 1.4, 0); ctx.lineTo(-s, s * 0.8); ctx.lineTo(-s, -s * 0.8);
    ctx.closePath(); ctx.fill(); ctx.stroke();
    ctx.restore();
  }
}

function line(ctx, pts, X, Y, colour, width) {
  if (pts.length < 2) return;
  ctx.strokeStyle = colour; ctx.lineWidth = width; ctx.lineJoin = "round";
  ctx.beginPath();
  ctx.moveTo(X(pts[0][0]), Y(pts[0][1]));
  for (const [x, y] of pts.slice(1)) ctx.lineTo(X(x), Y(y));
  ctx.stroke();
}

connect();
