// guidebelt view: draws the frames the server pushes on /ws. Read-only; no library, no build.
"use strict";

const $ = (id) => document.getElementById(id);
const mapCanvas = $("map"), beltCanvas = $("belt"), select = $("user");
const MOTORS = ["front", "right", "back", "left"];
let frame = null, chosen = null, mapImage = null, mapKey = "", arrivals = [];

function connect() {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  const ws = new WebSocket(`${scheme}//${location.host}/ws`);
  ws.onopen = () => { $("conn").textContent = "live"; $("conn").className = "up"; };
  ws.onmessage = (event) => { frame = JSON.parse(event.data); tally(); draw(); };
  // The view or the daemon restarted: try again every second, for as long as the page is open.
  ws.onclose = () => { $("conn").textContent = "offline"; $("conn").className = ""; setTimeout(connect, 1000); };
}

function tally() {
  const now = performance.now();
  arrivals.push(now);
  while (arrivals.length && now - arrivals[0] > 2000) arrivals.shift();
  $("rate").textContent = `${(arrivals.length / 2).toFixed(1)} Hz`;
}

function users() {
  const names = Object.keys(frame.users);
  if (select.options.length !== names.length || names.some((n, i) => select.options[i].value !== n)) {
    select.replaceChildren(...names.map((n) => new Option(n, n)));
  }
  if (!names.includes(chosen)) chosen = names[0] ?? null;
  select.value = chosen ?? "";
  return chosen ? frame.users[chosen] : null;
}

select.onchange = () => { chosen = select.value; draw(); };

function draw() {
  $("daemon").textContent = `daemon: ${frame.daemon_alive ? "alive" : "gone"}`;
  const u = users();
  drawMap(u);
  drawBelt(u && u.belt);
  drawText(u);
}

function loadMap(u) {
  const key = `${chosen}/${u.map.version}`;
  if (key === mapKey || !u.map.version) return;
  mapKey = key;
  const img = new Image();
  img.onload = () => { mapImage = img; if (frame) drawMap(frame.users[chosen]); };
  img.src = `/map/${encodeURIComponent(chosen)}.png?v=${u.map.version}`;
}

function drawMap(u) {
  const ctx = mapCanvas.getContext("2d");
  ctx.fillStyle = "#fafafa";
  ctx.fillRect(0, 0, mapCanvas.width, mapCanvas.height);
  if (!u || !u.map.height) return;
  loadMap(u);
  const h = u.map.height, w = u.map.width, s = Math.min(mapCanvas.width / w, mapCanvas.height / h);
  const cell = frame.cell_m;
  if (mapImage) { ctx.imageSmoothingEnabled = false; ctx.drawImage(mapImage, 0, 0, w * s, h * s); }
  // (row, col) → canvas; metres (x east, y north) → canvas, row 0 at the top.
  const rc = ([r, c]) => [(c + 0.5) * s, (r + 0.5) * s];
  const xy = (x, y) => [(x / cell) * s, (h - y / cell) * s];
  if (u.path.length > 1) {
    ctx.strokeStyle = "#1565c0"; ctx.lineWidth = Math.max(2, s * 0.6); ctx.lineJoin = "round";
    ctx.beginPath();
    u.path.forEach((p, i) => { const [px, py] = rc(p); i ? ctx.lineTo(px, py) : ctx.moveTo(px, py); });
    ctx.stroke();
  }
  if (u.goal && u.goal.x !== undefined) {
    const [gx, gy] = xy(u.goal.x, u.goal.y), r = Math.max(6, s * 2);
    ctx.fillStyle = "#2e7d32"; ctx.beginPath(); ctx.arc(gx, gy, r, 0, 2 * Math.PI); ctx.fill();
    ctx.strokeStyle = "#fff"; ctx.lineWidth = 2; ctx.beginPath();
    ctx.moveTo(gx - r / 2, gy); ctx.lineTo(gx + r / 2, gy); ctx.moveTo(gx, gy - r / 2); ctx.lineTo(gx, gy + r / 2); ctx.stroke();
  }
  if (u.pose) {
    const [px, py] = xy(u.pose.x, u.pose.y), r = Math.max(6, s * 2.5), a = u.pose.heading;
    ctx.fillStyle = "#e65100"; ctx.beginPath(); ctx.arc(px, py, r, 0, 2 * Math.PI); ctx.fill();
    // Heading: 0 = east, counter-clockwise positive; the canvas's y grows downwards.
    ctx.strokeStyle = "#e65100"; ctx.lineWidth = 3; ctx.beginPath(); ctx.moveTo(px, py);
    ctx.lineTo(px + Math.cos(a) * r * 2.6, py - Math.sin(a) * r * 2.6); ctx.stroke();
  }
}

function drawBelt(belt) {
  const ctx = beltCanvas.getContext("2d"), cx = beltCanvas.width / 2, cy = beltCanvas.height / 2;
  ctx.clearRect(0, 0, beltCanvas.width, beltCanvas.height);
  ctx.strokeStyle = "#999"; ctx.lineWidth = 6;
  ctx.beginPath(); ctx.ellipse(cx, cy, 80, 62, 0, 0, 2 * Math.PI); ctx.stroke();
  ctx.fillStyle = "#555"; ctx.font = "12px system-ui"; ctx.textAlign = "center";
  ctx.fillText("front", cx, 14);
  const spots = [[cx, cy - 62], [cx + 80, cy], [cx, cy + 62], [cx - 80, cy]];
  MOTORS.forEach((name, i) => {
    const v = belt ? belt.motors[i] : 0, [x, y] = spots[i];
    ctx.fillStyle = `rgb(${255}, ${Math.round(235 - 0.8 * v)}, ${Math.round(225 - 0.85 * v)})`;
    ctx.strokeStyle = "#333"; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(x, y, 10 + v / 16, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
    ctx.fillStyle = "#000"; ctx.fillText(String(v), x, y + 4);
  });
}

function drawText(u) {
  const st = u && u.status, belt = u && u.belt;
  $("pattern").textContent = belt ? `${belt.kind}${belt.period_ms ? `, pulse ${belt.period_ms} ms` : ""}` : "-";
  $("motors").textContent = belt ? MOTORS.map((m, i) => `${m} ${belt.motors[i]}`).join(", ") : "-";
  $("state").textContent = st ? st.state + (st.paused ? " (paused)" : "") : "-";
  $("code").textContent = st ? (st.code || "ok") : "-";
  $("reason").textContent = st && st.reason ? st.reason : "-";
  $("distance").textContent = st && st.distance_m != null ? `${st.distance_m.toFixed(1)} m` : "-";
  $("replans").textContent = st ? String(st.replans) : "-";
  $("pose").textContent = u && u.pose ? `${u.pose.x.toFixed(2)}, ${u.pose.y.toFixed(2)} m, ${(u.pose.heading * 180 / Math.PI).toFixed(0)}°` : "-";
  $("latency").textContent = u && u.latency_ms != null ? `${u.latency_ms.toFixed(1)} ms` : "-";
  const items = (u ? u.cues : []).map((c) => { const li = document.createElement("li"); li.textContent = c.text; return li; });
  $("cues").replaceChildren(...items);
}

connect();
