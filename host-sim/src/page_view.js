// report.html's 3D view (host-sim/src/page.rs): a perspective camera orbiting the map's centre,
// drawn on a 2D canvas. World frame: the run's first keyframe's camera (x right, y down, z
// forward), so screen y follows world y.
"use strict";
window.addEventListener("error", (e) => {
  document.body.dataset.error = String(e.message);
});
(function () {
  const data = JSON.parse(document.getElementById("scene").textContent);
  const canvas = document.getElementById("view");
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  const OBJECT_COLOURS = ["#e62828", "#285af0", "#28c83c"];

  // The view's centre and size: the trajectory's and keyframes' bounds (the points may hold
  // far outliers).
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  const grow = (p) => {
    for (let i = 0; i < 3; i++) {
      lo[i] = Math.min(lo[i], p[i]);
      hi[i] = Math.max(hi[i], p[i]);
    }
  };
  data.trajectory.forEach(grow);
  data.keyframes.forEach(grow);
  // The points' bulk: the 5th and 95th percentiles on each axis.
  if (data.points.length > 20) {
    for (let i = 0; i < 3; i++) {
      const v = data.points.map((p) => p[i]).sort((a, b) => a - b);
      lo[i] = Math.min(lo[i], v[Math.floor(0.05 * v.length)]);
      hi[i] = Math.max(hi[i], v[Math.floor(0.95 * v.length)]);
    }
  }
  const centre = isFinite(lo[0]) ? lo.map((l, i) => (l + hi[i]) / 2) : [0, 0, 0];
  const radius = isFinite(lo[0])
    ? Math.max(0.5, ...hi.map((h, i) => (h - lo[i]) / 2)) : 1;
  let yaw = 0.5, pitch = -0.35, dist = 2.4 * radius;
  const focal = 0.9 * W;

  // Screen position and depth of world point p, or null behind the viewer.
  function project(p) {
    const x = p[0] - centre[0], y = p[1] - centre[1], z = p[2] - centre[2];
    const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
    const x1 = cy * x + sy * z, z1 = -sy * x + cy * z;
    const y2 = cp * y - sp * z1, z2 = sp * y + cp * z1 + dist;
    if (z2 < 0.05 * radius) return null;
    return [W / 2 + (focal * x1) / z2, H / 2 + (focal * y2) / z2, z2];
  }

  function polyline(points, colour, width) {
    ctx.strokeStyle = colour;
    ctx.lineWidth = width;
    ctx.beginPath();
    let open = false, drawn = 0;
    for (const p of points) {
      const s = project(p);
      if (!s) { open = false; continue; }
      if (open) ctx.lineTo(s[0], s[1]); else ctx.moveTo(s[0], s[1]);
      open = true;
      drawn++;
    }
    ctx.stroke();
    return drawn;
  }

  function dots(points, colour, size) {
    ctx.fillStyle = colour;
    let drawn = 0;
    for (const p of points) {
      const s = project(p);
      if (s) { ctx.fillRect(s[0] - size / 2, s[1] - size / 2, size, size); drawn++; }
    }
    return drawn;
  }

  // Two unit vectors across the unit normal n.
  function across(n) {
    const a = Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
    const cross = (u, v) => [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    const e1 = cross(n, a), l = Math.hypot(...e1);
    const u = e1.map((c) => c / l);
    return [u, cross(n, u)];
  }
  const at = (p, e1, e2, s, t) => [0, 1, 2].map((i) => p[i] + e1[i] * s + e2[i] * t);

  function draw() {
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, W, H);
    let drawn = 0;
    drawn += dots(data.points, "#999999", 1.5);
    drawn += dots(data.newest, "#e02020", 2.5);
    for (const pl of data.planes) {
      const c = pl.slice(0, 3), [e1, e2] = across(pl.slice(3, 6)), h = 0.2;
      const corners = [[-h, -h], [h, -h], [h, h], [-h, h]].map(([s, t]) => project(at(c, e1, e2, s, t)));
      if (corners.some((s) => !s)) continue;
      ctx.fillStyle = "rgba(128,176,255,0.35)";
      ctx.beginPath();
      corners.forEach((s, i) => (i ? ctx.lineTo(s[0], s[1]) : ctx.moveTo(s[0], s[1])));
      ctx.closePath();
      ctx.fill();
      drawn++;
    }
    if (data.ground_truth.length) drawn += polyline(data.ground_truth, "#20a040", 1.5);
    drawn += polyline(data.trajectory, "#0050ff", 2.5);
    for (const k of data.keyframes) {
      const tip = [0, 1, 2].map((i) => k[i] + 0.06 * radius * k[i + 3]);
      drawn += polyline([k.slice(0, 3), tip], "#ff9900", 2);
    }
    ctx.strokeStyle = "#d000d0";
    ctx.lineWidth = 2;
    for (const p of data.loops) {
      const s = project(p);
      if (s) { ctx.beginPath(); ctx.arc(s[0], s[1], 8, 0, 2 * Math.PI); ctx.stroke(); drawn++; }
    }
    for (const a of data.anchors) {
      const p = a.slice(0, 3), up = a.slice(3, 6), side = 0.15 * a[6];
      const [e1, e2] = across(up);
      const corner = (i) => {
        const b = at(p, e1, e2, ((i & 1) - 0.5) * side, (((i >> 1) & 1) - 0.5) * side);
        return [0, 1, 2].map((j) => b[j] + up[j] * (i >> 2) * side);
      };
      const colour = OBJECT_COLOURS[a[7] % OBJECT_COLOURS.length];
      for (const [i, j] of [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]]) {
        drawn += polyline([corner(i), corner(j)], colour, 2) > 0 ? 1 : 0;
      }
    }
    document.body.dataset.drawn = String(drawn);
  }

  let dragging = null;
  canvas.addEventListener("pointerdown", (e) => { dragging = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointerup", () => { dragging = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (!dragging) return;
    yaw += (e.clientX - dragging[0]) * 0.01;
    pitch = Math.max(-1.5, Math.min(1.5, pitch + (e.clientY - dragging[1]) * 0.01));
    dragging = [e.clientX, e.clientY];
    draw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    dist = Math.max(0.1 * radius, dist * Math.exp(e.deltaY * 0.001));
    draw();
  }, { passive: false });
  draw();
})();
