// The page of a cpbc run: the 3-D scene (meshcat) and the time plots under one timeline.
// Reads window.CPBC_DATA (written by cpbc/viewer/page_data.py) and exposes window.cpbc, which
// the tests drive: seek(t), selectCase(name), play(), pause(), and the current state.
"use strict";

(async function () {
  const DATA = window.CPBC_DATA;
  if (!("DecompressionStream" in window)) {
    document.body.textContent = "This page needs a browser with DecompressionStream " +
      "(Chrome 80, Firefox 113, Safari 16.4 or later).";
    return;
  }
  // A run's page carries meshcat's script deflated (cpbc/viewer/export.py); run it first.
  const meshcatDeflated = document.getElementById("meshcat-deflated");
  if (typeof MeshCat === "undefined" && meshcatDeflated) {
    const code = new TextDecoder().decode(await inflate(meshcatDeflated.textContent.trim()));
    (0, eval)(code);  // global scope, as a <script> element would run it
  }
  await unpackAll(DATA);
  const THREE = MeshCat.THREE;
  const STYLES = [[], [6, 4], [1.5, 3]];  // named constraints: solid, dashed, dotted

  // -- data -------------------------------------------------------------------------------
  // Arrays arrive deflated (cpbc/viewer/page_data.py, `packed`): {deflated} is bytes; with a
  // stride, float32 rows of `stride` values, stored as the byte planes of the differences
  // between successive rows' bit patterns.
  async function inflate(b64) {
    const bytes = Uint8Array.from(atob(b64), ch => ch.charCodeAt(0));
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Uint8Array(await new Response(stream).arrayBuffer());
  }
  function floats(planes, stride) {
    const n = planes.length / 4, bits = new Uint32Array(n);
    for (let i = 0; i < n; i++) {
      bits[i] = planes[i] | planes[n + i] << 8 | planes[2 * n + i] << 16 | planes[3 * n + i] << 24;
    }
    for (let i = stride; i < n; i++) bits[i] += bits[i - stride];  // wraps as the differences did
    return new Float32Array(bits.buffer);
  }
  // Every packed entry under `root` replaced by its array, all inflated concurrently.
  async function unpackAll(root) {
    const jobs = [];
    (function walk(node) {
      for (const [key, value] of Object.entries(node)) {
        if (value === null || typeof value !== "object") continue;
        if (typeof value.deflated !== "string") { walk(value); continue; }
        jobs.push(inflate(value.deflated).then(bytes => {
          node[key] = "stride" in value ? floats(bytes, value.stride) : bytes;
        }));
      }
    })(root);
    await Promise.all(jobs);
  }
  function replay(viewer, commands) {
    for (const bytes of commands) viewer.handle_command_bytearray(bytes);
  }
  // Scene paths as the Python side names them; meshcat files them under "meshcat".
  function path(p) { return ["meshcat"].concat(p.split("/").filter(x => x.length > 0)); }
  function hex(colour) { return new THREE.Color(colour); }

  // Clearance colour as cpbc.results.palette.clearance_colour: the base colour far away,
  // the warning colour at zero clearance, linear in between.
  function blend(base, warning, clearance, warn) {
    const w = Math.min(Math.max(1 - clearance / warn, 0), 1);
    return [0, 1, 2].map(i => (1 - w) * base[i] + w * warning[i]);
  }
  function rgb(colour) { const c = hex(colour); return [c.r, c.g, c.b]; }

  // -- the 3-D scene ----------------------------------------------------------------------
  const pane = document.getElementById("meshcat-pane");
  const viewer = new MeshCat.Viewer(pane);
  window.viewer = viewer;
  replay(viewer, DATA.commands);

  function cloneBody(body, colour, opacity) {
    const group = new THREE.Group();
    const materials = [];
    for (const g of body.geoms) {
      const copy = viewer.scene_tree.find(path(g)).object.clone(true);
      copy.visible = true;
      copy.traverse(o => {
        if (o.isMesh) {
          o.material = o.material.clone();
          o.material.color.set(colour);
          o.material.opacity = opacity;
          o.material.transparent = opacity < 1;
          materials.push(o.material);
        }
      });
      group.add(copy);
    }
    return { group, materials };
  }

  const warningRgb = rgb(DATA.colours.warning);
  const obstacleRgb = rgb(DATA.colours.obstacle);
  // The traced point's path as a thin tube (WebGL draws lines one pixel wide); points
  // nearer than the radius to the last kept one are dropped.
  function traceTube(tip, colour) {
    const pts = [];
    for (let k = 0; k < tip.length; k += 3) {
      const p = new THREE.Vector3(tip[k], tip[k + 1], tip[k + 2]);
      if (!pts.length || p.distanceTo(pts[pts.length - 1]) >= DATA.traceRadius) pts.push(p);
    }
    if (pts.length < 2) return null;
    const curve = new THREE.CatmullRomCurve3(pts, false, "centripetal");
    return new THREE.Mesh(new THREE.TubeGeometry(curve, Math.min(4 * pts.length, 4000),
                                                 DATA.traceRadius, 6, false),
                          new THREE.MeshPhongMaterial({ color: colour }));
  }

  const cases = DATA.cases.map(c => {
    const runs = c.controllers.map(r => {
      const root = path(c.root).concat([r.name.replace(/\//g, "_") || "_"]);
      const bodies = DATA.bodies.map(b => {
        const { group, materials } = cloneBody(b, r.colour, DATA.opacity);
        const bodyPath = root.concat(["robot", b.name.replace(/\//g, "_") || "_"]);
        viewer.set_object(bodyPath, group);
        return { node: viewer.scene_tree.find(bodyPath).object, materials };
      });
      const tip = new THREE.Mesh(new THREE.SphereGeometry(DATA.markerRadius, 16, 12),
                                 new THREE.MeshPhongMaterial({ color: r.colour }));
      viewer.set_object(root.concat(["tip"]), tip);
      const tipData = r.tip;
      const tube = traceTube(tipData, r.colour);
      if (tube) viewer.set_object(root.concat(["trace"]), tube);
      return {
        name: r.name, colour: r.colour, base: rgb(r.colour), status: r.status,
        frames: r.frames, pose: r.pose, tip: tipData,
        tipNode: viewer.scene_tree.find(root.concat(["tip"])).object,
        clearance: r.clearance, bodies,
      };
    });
    return {
      name: c.name, duration: c.duration, root: path(c.root), runs, plots: c.plots,
      series: c.series, obstacleClearance: c.obstacleClearance,
    };
  });
  const obstacleMaterials = DATA.obstacles.map(p => {
    const node = viewer.scene_tree.find(path(p).concat(["<object>"]));
    return node.object && node.object.material ? node.object.material : null;
  });

  function poseCase(c, t) {
    const nb = DATA.bodies.length;
    for (const r of c.runs) {
      const k = Math.min(Math.max(Math.round(t * DATA.fps), 0), r.frames - 1);
      for (let b = 0; b < nb; b++) {
        const o = (k * nb + b) * 7, p = r.pose, node = r.bodies[b].node;
        node.position.set(p[o], p[o + 1], p[o + 2]);
        node.quaternion.set(p[o + 3], p[o + 4], p[o + 5], p[o + 6]);
        if (r.clearance) {
          const colour = blend(r.base, warningRgb, r.clearance[k * nb + b], DATA.warnDistance);
          for (const m of r.bodies[b].materials) m.color.setRGB(colour[0], colour[1], colour[2]);
        }
      }
      r.tipNode.position.set(r.tip[3 * k], r.tip[3 * k + 1], r.tip[3 * k + 2]);
    }
    if (c.obstacleClearance) {
      const no = DATA.obstacles.length;
      const frames = c.obstacleClearance.length / no;
      const k = Math.min(Math.max(Math.round(t * DATA.fps), 0), frames - 1);
      obstacleMaterials.forEach((m, j) => {
        if (!m) return;
        const colour = blend(obstacleRgb, warningRgb, c.obstacleClearance[k * no + j],
                             DATA.warnDistance);
        m.color.setRGB(colour[0], colour[1], colour[2]);
      });
    }
    viewer.set_dirty();
  }

  // -- plots ------------------------------------------------------------------------------
  function niceStep(span, count) {
    const raw = span / Math.max(count, 1);
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const f = raw / mag;
    return mag * (f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10);
  }
  function fmt(v) {
    const a = Math.abs(v);
    return a !== 0 && (a < 1e-3 || a >= 1e4) ? v.toExponential(1) : +v.toPrecision(4) + "";
  }

  // Which columns a panel draws, per run: [{key, style, band}]
  function panelColumns(panel) {
    if (panel.key !== "margins") return [{ key: panel.key + panel.column, style: 0 }];
    const out = panel.named.map((i, j) => ({ key: "m" + i, style: j }));
    if (panel.others.length) out.push({ band: ["lo" + panel.label, "hi" + panel.label] });
    return out;
  }

  function yRange(c, panel) {
    let lo = Infinity, hi = -Infinity;
    const take = v => { if (Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } };
    for (const s of c.series) {
      for (const col of panelColumns(panel)) {
        if (col.band) {
          // the far constraints' range must not squash the near ones: their lower edge only
          s.columns[col.band[0]].forEach(take);
        } else {
          s.columns[col.key].forEach(take);
        }
      }
    }
    for (const line of panel.lines) take(line.y);
    if (!Number.isFinite(lo)) { lo = -1; hi = 1; }
    if (hi - lo < 1e-12) { lo -= 0.5 * Math.max(Math.abs(lo), 1e-3); hi += 0.5 * Math.max(Math.abs(hi), 1e-3); }
    const pad = 0.06 * (hi - lo);
    return [lo - pad, hi + pad];
  }

  const M = { left: 52, right: 8, top: 16, bottom: 20 };

  function drawStatic(view) {
    const { canvas, panel, c } = view;
    const dpr = window.devicePixelRatio || 1;
    const w = canvas.clientWidth, h = canvas.clientHeight;
    canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr);
    const ctx = canvas.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    const [y0, y1] = yRange(c, panel);
    const x = t => M.left + (w - M.left - M.right) * t / c.duration;
    const y = v => h - M.bottom - (h - M.top - M.bottom) * (v - y0) / (y1 - y0);
    view.x = x; view.y = y; view.t = px => (px - M.left) / (w - M.left - M.right) * c.duration;
    // grid and ticks
    ctx.font = "10px system-ui, sans-serif"; ctx.fillStyle = "#555"; ctx.strokeStyle = "#e4e6ea";
    ctx.lineWidth = 1;
    const ys = niceStep(y1 - y0, 4);
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    for (let v = Math.ceil(y0 / ys) * ys; v <= y1; v += ys) {
      ctx.beginPath(); ctx.moveTo(M.left, y(v)); ctx.lineTo(w - M.right, y(v)); ctx.stroke();
      ctx.fillText(fmt(Math.abs(v) < ys * 1e-9 ? 0 : v), M.left - 4, y(v));
    }
    const xs = niceStep(c.duration, Math.max(2, Math.floor((w - M.left) / 70)));
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (let t = 0; t <= c.duration + 1e-9; t += xs) {
      ctx.beginPath(); ctx.moveTo(x(t), M.top); ctx.lineTo(x(t), h - M.bottom); ctx.stroke();
      ctx.fillText(fmt(t), x(t), h - M.bottom + 3);
    }
    ctx.textAlign = "left"; ctx.textBaseline = "top"; ctx.fillStyle = "#222";
    ctx.font = "11px system-ui, sans-serif";
    ctx.fillText(panel.label, M.left + 2, 1);
    ctx.save();
    ctx.beginPath(); ctx.rect(M.left, M.top, w - M.left - M.right, h - M.top - M.bottom); ctx.clip();
    // reference lines: bounds, limits, target, boundary
    for (const line of panel.lines) {
      ctx.strokeStyle = line.warning ? DATA.colours.warning : DATA.colours.bound;
      ctx.setLineDash([5, 4]); ctx.lineWidth = 1;
      ctx.beginPath(); ctx.moveTo(M.left, y(line.y)); ctx.lineTo(w - M.right, y(line.y)); ctx.stroke();
    }
    ctx.setLineDash([]);
    c.series.forEach((s, k) => {
      const colour = c.runs[k].colour;
      for (const col of panelColumns(panel)) {
        if (col.band) {
          const lo = s.columns[col.band[0]], hi = s.columns[col.band[1]];
          ctx.fillStyle = colour; ctx.globalAlpha = 0.15; ctx.beginPath();
          for (let i = 0; i < s.time.length; i++) ctx.lineTo(x(s.time[i]), y(hi[i]));
          for (let i = s.time.length - 1; i >= 0; i--) ctx.lineTo(x(s.time[i]), y(lo[i]));
          ctx.closePath(); ctx.fill(); ctx.globalAlpha = 1;
          continue;
        }
        const v = s.columns[col.key];
        ctx.strokeStyle = colour; ctx.lineWidth = 1.5; ctx.setLineDash(STYLES[col.style]);
        ctx.beginPath();
        let pen = false;
        for (let i = 0; i < s.time.length; i++) {
          if (!Number.isFinite(v[i])) { pen = false; continue; }
          if (pen) ctx.lineTo(x(s.time[i]), y(v[i])); else ctx.moveTo(x(s.time[i]), y(v[i]));
          pen = true;
        }
        ctx.stroke(); ctx.setLineDash([]);
      }
    });
    ctx.restore();
    view.image = ctx.getImageData(0, 0, canvas.width, canvas.height);
  }

  function valueAt(time, v, t) {
    let lo = 0, hi = time.length - 1;
    while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (time[mid] <= t) lo = mid; else hi = mid; }
    return Math.abs(time[hi] - t) < Math.abs(time[lo] - t) ? v[hi] : v[lo];
  }

  function drawCursor(view, t) {
    const { canvas, panel, c } = view;
    if (!view.image) return;
    const ctx = canvas.getContext("2d");
    const dpr = window.devicePixelRatio || 1;
    ctx.putImageData(view.image, 0, 0);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    const h = canvas.clientHeight;
    ctx.strokeStyle = "#222"; ctx.lineWidth = 1; ctx.setLineDash([]);
    const cx = Math.round(view.x(t)) + 0.5;  // on a pixel column: a crisp line
    ctx.beginPath(); ctx.moveTo(cx, M.top); ctx.lineTo(cx, h - M.bottom); ctx.stroke();
    const first = panelColumns(panel).find(col => !col.band);
    if (!first) return;
    c.series.forEach((s, k) => {
      const v = valueAt(s.time, s.columns[first.key], t);
      if (!Number.isFinite(v)) return;
      ctx.fillStyle = c.runs[k].colour;
      ctx.beginPath(); ctx.arc(view.x(t), view.y(v), 3, 0, 2 * Math.PI); ctx.fill();
    });
  }

  function keyHtml(c, panel) {
    const parts = [];
    if (panel.key === "margins") {
      panel.names.forEach((n, j) => parts.push(
        `<span><span class="dash" style="border-top-style:${["solid", "dashed", "dotted"][j]}"></span>${escapeHtml(n)}</span>`));
      if (panel.others.length) parts.push(`<span><span class="band"></span>range of ${panel.others.length} others</span>`);
    }
    for (const line of panel.lines) {
      if (line.label) parts.push(`<span><span class="dash" style="border-top-style:dashed;border-color:${line.warning ? DATA.colours.warning : DATA.colours.bound}"></span>${escapeHtml(line.label)}</span>`);
    }
    return parts.join("");
  }
  function escapeHtml(s) {
    return String(s).replace(/[&<>"']/g, ch => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[ch]);
  }

  // -- page state -------------------------------------------------------------------------
  const state = { caseIndex: 0, time: 0, playing: false, speed: 1, tab: 0, views: [] };
  const slider = document.getElementById("time");
  const clock = document.getElementById("clock");
  const playButton = document.getElementById("play");
  const caseSelect = document.getElementById("case");
  const tabs = document.getElementById("tabs");
  const panelsDiv = document.getElementById("panels");
  const legend = document.getElementById("legend");

  function current() { return cases[state.caseIndex]; }

  function buildPanels() {
    const c = current();
    panelsDiv.innerHTML = "";
    state.views = [];
    const group = c.plots[Math.min(state.tab, c.plots.length - 1)];
    for (const panel of group.panels) {
      const fig = document.createElement("figure");
      fig.className = "panel";
      const canvas = document.createElement("canvas");
      const key = document.createElement("div");
      key.className = "key";
      key.innerHTML = keyHtml(c, panel);
      fig.appendChild(canvas); fig.appendChild(key);
      panelsDiv.appendChild(fig);
      const view = { canvas, panel, c };
      state.views.push(view);
      const seekAt = ev => {
        const r = canvas.getBoundingClientRect();
        seek(view.t(ev.clientX - r.left));
      };
      canvas.addEventListener("pointerdown", ev => { pause(); seekAt(ev); canvas.setPointerCapture(ev.pointerId); });
      canvas.addEventListener("pointermove", ev => { if (ev.buttons) seekAt(ev); });
    }
    for (const view of state.views) { drawStatic(view); drawCursor(view, state.time); }
  }

  function buildTabs() {
    tabs.innerHTML = "";
    current().plots.forEach((g, i) => {
      const b = document.createElement("button");
      b.type = "button"; b.textContent = g.title;
      b.className = i === state.tab ? "active" : "";
      b.addEventListener("click", () => { state.tab = i; buildTabs(); buildPanels(); });
      tabs.appendChild(b);
    });
  }

  function buildLegend() {
    const c = current();
    const rows = [`<b>${escapeHtml(DATA.title)} — case '${escapeHtml(c.name)}'</b>`];
    for (const r of c.runs) {
      rows.push(`<div><span class="swatch" style="background:${r.colour}"></span>${escapeHtml(r.name)}` +
                (r.status ? ` — ${escapeHtml(r.status)}` : "") + "</div>");
    }
    rows.push('<div><span class="swatch" style="background:#3a3a3a;opacity:.4"></span>target pose</div>');
    if (DATA.obstacles.length) {
      rows.push(`<div class="note">links and obstacles turn red as their clearance falls from ${DATA.warnDistance} m to 0</div>`);
    }
    legend.innerHTML = rows.join("");
  }

  function selectCase(name) {
    const i = cases.findIndex(c => c.name === name);
    if (i < 0) throw new Error(`no case '${name}'`);
    state.caseIndex = i;
    caseSelect.value = name;
    cases.forEach((c, j) => { viewer.scene_tree.find(c.root).object.visible = j === i; });
    slider.max = current().duration;
    buildLegend(); buildTabs(); buildPanels();
    seek(Math.min(state.time, current().duration));
    return true;
  }

  function seek(t) {
    const c = current();
    state.time = Math.min(Math.max(Number(t) || 0, 0), c.duration);
    slider.value = state.time;
    clock.textContent = `t = ${state.time.toFixed(2)} s of ${c.duration.toFixed(2)} s`;
    poseCase(c, state.time);
    for (const view of state.views) drawCursor(view, state.time);
    return state.time;
  }

  let last = null;
  function tick(now) {
    if (!state.playing) { last = null; return; }
    if (last !== null) {
      const t = state.time + state.speed * (now - last) / 1000;
      seek(t);
      if (t >= current().duration) pause();
    }
    last = now;
    if (state.playing) requestAnimationFrame(tick);
  }
  function play() {
    if (state.time >= current().duration) seek(0);
    state.playing = true; playButton.textContent = "❚❚"; last = null;
    requestAnimationFrame(tick);
  }
  function pause() { state.playing = false; playButton.textContent = "▶"; }

  // -- wiring -----------------------------------------------------------------------------
  document.getElementById("title").textContent = DATA.title;
  document.title = `cpbc: ${DATA.title}`;
  for (const c of cases) {
    const o = document.createElement("option");
    o.value = c.name; o.textContent = c.name;
    caseSelect.appendChild(o);
  }
  caseSelect.addEventListener("change", () => selectCase(caseSelect.value));
  slider.addEventListener("input", () => { pause(); seek(parseFloat(slider.value)); });
  playButton.addEventListener("click", () => (state.playing ? pause() : play()));
  document.getElementById("speed").addEventListener("change", ev => {
    state.speed = parseFloat(ev.target.value);
  });
  document.addEventListener("keydown", ev => {
    if (ev.code === "Space" && ev.target.tagName !== "INPUT" && ev.target.tagName !== "SELECT") {
      ev.preventDefault(); state.playing ? pause() : play();
    }
  });
  // meshcat sizes its canvas to the window; the scene has a pane of its own
  function resize() {
    viewer.set_3d_pane_size(pane.clientWidth, pane.clientHeight);
    for (const view of state.views) { drawStatic(view); drawCursor(view, state.time); }
  }
  window.onresize = resize;

  window.cpbc = {
    ready: false, data: DATA,
    get duration() { return current().duration; },
    get time() { return state.time; },
    get case() { return current().name; },
    get playing() { return state.playing; },
    get panels() { return state.views.map(v => v.panel.label); },
    frame(t) { return Math.round(t * DATA.fps); },
    cursorX(i) { return Math.round(state.views[i].x(state.time)); },
    seek, selectCase, play, pause,
    showTab(i) { state.tab = i; buildTabs(); buildPanels(); return true; },
  };
  resize();
  selectCase(cases[0].name);
  seek(current().duration);  // open on the end state, as the figures show it
  window.cpbc.ready = true;
})();
