// sgjax map editor: the browser side of `sgjax edit` (docs/editor.md).
// Plain JavaScript, no libraries. The page edits the map JSON of docs/maps.md in place (keys and
// their order are kept as the server sent them) and talks to the server's /api/... endpoints.
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const canvas = $("canvas");
  const ctx = canvas.getContext("2d");

  const TOOLS = { v: "select", w: "wall", n: "node", e: "edge", g: "group", z: "zone", s: "split", d: "delete" };
  const SNAP_PX = 10; // wall ends and nodes closer than this (screen px) attract points
  const HIT_PX = 8;
  const CHECK_DELAY_MS = 250;
  const AUTOSAVE_DELAY_MS = 2000;
  const HISTORY_LIMIT = 500;
  const COLORS = {
    wall: "#262b36", edge: "#7a8aa6", node: "#ffffff", nodeLine: "#3b4a66", start: "#16a34a",
    goal: "#dc2626", zone: "rgba(250, 204, 21, 0.22)", zoneLine: "rgba(202, 138, 4, 0.9)",
    select: "#2563eb", error: "#d11f1f", warning: "#e07b00", route: "rgba(37, 99, 235, 0.55)",
    tie: "#f97316", grid: "#eceef2", gridMajor: "#d9dce3", bounds: "#9aa3b2",
  };
  const ROBOT_COLORS = ["#2563eb", "#dc2626", "#16a34a", "#9333ea", "#ea580c", "#0891b2",
    "#be185d", "#65a30d", "#4f46e5", "#b45309"];

  const state = {
    map: null,
    file: "",
    root: "",
    history: [],
    historyIndex: -1,
    view: { cx: 0, cy: 0, scale: 40 },
    size: { w: 1, h: 1 },
    tool: "select",
    selection: null, // {kind: "node"|"wall"|"edge"|"zone", index}
    hover: null,
    drag: null,
    chain: null, // {x, y}: where the next wall of the chain starts
    edgeFrom: null, // node id the edge tool starts from
    group: { kind: "groups", index: 0, phase: "starts" },
    problems: [],
    routes: null,
    cursor: null, // {x, y} world, {px, py} screen
    spaceDown: false,
    ready: false,
    sessionLoaded: false,
    pending: { check: 0, save: 0, play: 0, routes: 0, generate: 0 },
    checkTimer: null,
    autosaveTimer: null,
    checkSeq: 0,
    routesSeq: 0,
    activeProblem: -1,
    playback: null,
    stopping: false, // Stop was pressed while a batch plays
    autosaveFailed: false,
    fieldsFor: "", // which element the selection fields show ("kind:index")
    fitted: false,
    redrawQueued: false,
  };

  // ---------------------------------------------------------------- small helpers

  const clone = (value) => JSON.parse(JSON.stringify(value));
  const round6 = (v) => Math.round(v * 1e6) / 1e6 + 0; // + 0 turns -0 into 0
  const fmt = (v, digits = 2) => Number(v).toFixed(digits);
  const plural = (n, word) => `${n} ${word}${n === 1 ? "" : "s"}`;
  const list = (key) => (state.map && Array.isArray(state.map[key]) ? state.map[key] : []);

  function deepEqual(a, b) {
    if (a === b) return true;
    if (typeof a !== typeof b || a === null || b === null || typeof a !== "object") return false;
    if (Array.isArray(a) !== Array.isArray(b)) return false;
    if (Array.isArray(a)) return a.length === b.length && a.every((v, i) => deepEqual(v, b[i]));
    const ka = Object.keys(a);
    const kb = Object.keys(b);
    return ka.length === kb.length && ka.every((k) => Object.prototype.hasOwnProperty.call(b, k) && deepEqual(a[k], b[k]));
  }

  function nodeIndexById() {
    const index = new Map();
    list("nodes").forEach((node, i) => index.set(node.id, i));
    return index;
  }

  function nodePosition(id, index = nodeIndexById()) {
    const i = index.get(id);
    return i === undefined ? null : list("nodes")[i].position;
  }

  function segmentDistance(px, py, x1, y1, x2, y2) {
    const dx = x2 - x1;
    const dy = y2 - y1;
    const len2 = dx * dx + dy * dy;
    let t = len2 > 0 ? ((px - x1) * dx + (py - y1) * dy) / len2 : 0;
    t = Math.max(0, Math.min(1, t));
    const qx = x1 + t * dx;
    const qy = y1 + t * dy;
    return { d: Math.hypot(px - qx, py - qy), t, x: qx, y: qy };
  }

  function message(text, kind = "") {
    const el = $("message");
    el.textContent = text;
    el.className = kind;
    el.title = text;
  }

  // This launch's secret (docs/editor.md, "Security"): `sgjax edit` opens /?token=...; every
  // API call carries it in a header that no other web page can send here.
  const TOKEN = new URLSearchParams(window.location.search).get("token") || "";

  async function api(path, body, signal) {
    const headers = { "X-Sgjax-Token": TOKEN };
    const init = body === undefined ? { method: "GET", headers } : {
      method: "POST", headers: { ...headers, "Content-Type": "application/json" }, body: JSON.stringify(body),
    };
    if (signal) init.signal = signal;
    let response;
    try {
      response = await fetch(path, init);
    } catch (err) {
      return { status: 0, ok: false, data: { error: `the server does not answer (${err.message})` } };
    }
    let data;
    try {
      data = await response.json();
    } catch (err) {
      data = { error: `HTTP ${response.status}: the answer is not JSON` };
    }
    if (data === null || typeof data !== "object") data = { error: `HTTP ${response.status}` };
    return { status: response.status, ok: response.ok, data };
  }

  // ---------------------------------------------------------------- view

  function worldToScreen(x, y) {
    const v = state.view;
    return [state.size.w / 2 + (x - v.cx) * v.scale, state.size.h / 2 - (y - v.cy) * v.scale];
  }

  function screenToWorld(px, py) {
    const v = state.view;
    return [v.cx + (px - state.size.w / 2) / v.scale, v.cy - (py - state.size.h / 2) / v.scale];
  }

  function contentBox(includeBounds) {
    let box = null;
    const add = (x, y) => {
      if (!Number.isFinite(x) || !Number.isFinite(y)) return;
      if (!box) box = [x, y, x, y];
      else box = [Math.min(box[0], x), Math.min(box[1], y), Math.max(box[2], x), Math.max(box[3], y)];
    };
    for (const w of list("walls")) { add(w[0], w[1]); add(w[2], w[3]); }
    for (const n of list("nodes")) add(n.position[0], n.position[1]);
    for (const z of list("zones")) { add(z.rect[0], z.rect[1]); add(z.rect[2], z.rect[3]); }
    if (includeBounds && state.map && Array.isArray(state.map.bounds)) {
      const b = state.map.bounds;
      add(b[0], b[1]);
      add(b[2], b[3]);
    }
    return box;
  }

  function fitView() {
    const box = contentBox(true) || [-5, -5, 5, 5];
    const w = Math.max(box[2] - box[0], 1);
    const h = Math.max(box[3] - box[1], 1);
    const scale = Math.min(state.size.w / w, state.size.h / h) * 0.92;
    state.view = { cx: (box[0] + box[2]) / 2, cy: (box[1] + box[3]) / 2, scale: Math.max(0.5, Math.min(scale, 2000)) };
    redraw();
  }

  function centreOn(x, y) {
    state.view.cx = x;
    state.view.cy = y;
    redraw();
  }

  function zoomAt(px, py, factor) {
    const [wx, wy] = screenToWorld(px, py);
    const scale = Math.max(0.5, Math.min(state.view.scale * factor, 5000));
    state.view.scale = scale;
    // keep (wx, wy) under the cursor
    state.view.cx = wx - (px - state.size.w / 2) / scale;
    state.view.cy = wy + (py - state.size.h / 2) / scale;
    redraw();
  }

  function resize() {
    const rect = canvas.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    state.size = { w: Math.max(1, rect.width), h: Math.max(1, rect.height) };
    canvas.width = Math.round(state.size.w * dpr);
    canvas.height = Math.round(state.size.h * dpr);
    if (state.map && !state.fitted && rect.width > 10) {
      state.fitted = true;
      fitView();
    }
    redraw();
  }

  // ---------------------------------------------------------------- history and change tracking

  function snapshot() {
    return JSON.stringify(state.map);
  }

  function pushSnapshot() {
    if (!state.map) return false;
    const s = snapshot();
    if (s === state.history[state.historyIndex]) return false;
    state.history = state.history.slice(0, state.historyIndex + 1);
    state.history.push(s);
    if (state.history.length > HISTORY_LIMIT) state.history.shift();
    state.historyIndex = state.history.length - 1;
    updateUndoButtons();
    return true;
  }

  function updateUndoButtons() {
    $("undo").disabled = state.historyIndex <= 0;
    $("redo").disabled = state.historyIndex >= state.history.length - 1;
  }

  // Everything that changes the map ends here: redraw, refresh the panels, re-check, autosave,
  // and (commit) keep an undo snapshot.
  function changed(commit = true) {
    if (commit) pushSnapshot();
    refreshPanels();
    scheduleCheck();
    scheduleAutosave();
    redraw();
  }

  function restore(index) {
    state.historyIndex = index;
    state.map = JSON.parse(state.history[index]);
    state.selection = null;
    state.chain = null;
    state.edgeFrom = null;
    state.drag = null;
    syncInputs();
    updateUndoButtons();
    changed(false);
  }

  function undo() {
    pushSnapshot(); // an uncommitted text edit becomes a step of its own
    if (state.historyIndex > 0) restore(state.historyIndex - 1);
  }

  function redo() {
    if (state.historyIndex < state.history.length - 1) restore(state.historyIndex + 1);
  }

  function setMap(map, commit = true) {
    state.map = clone(map);
    state.selection = null;
    state.chain = null;
    state.edgeFrom = null;
    syncInputs();
    changed(commit);
  }

  // ---------------------------------------------------------------- check, routes, autosave

  function scheduleCheck() {
    if (!state.sessionLoaded) return;
    clearTimeout(state.checkTimer);
    state.checkTimer = setTimeout(() => {
      state.checkTimer = null;
      runCheck();
      if ($("routes").checked) runRoutes();
    }, CHECK_DELAY_MS);
  }

  async function runCheck() {
    const seq = ++state.checkSeq;
    state.pending.check++;
    try {
      const r = await api("/api/check", { map: state.map });
      if (seq !== state.checkSeq) return;
      if (r.ok && Array.isArray(r.data.problems)) {
        showProblems(r.data.problems);
      } else {
        message(`check failed: ${r.data.error || r.status}`, "error");
      }
    } finally {
      state.pending.check--;
      if (state.sessionLoaded && !state.ready && seq === state.checkSeq) state.ready = true;
    }
  }

  async function runRoutes() {
    const seq = ++state.routesSeq;
    state.pending.routes++;
    try {
      const r = await api("/api/routes", { map: state.map });
      if (seq !== state.routesSeq) return;
      // a map with errors has no routes: say so on the canvas, not in the message line
      state.routes = r.ok ? r.data : { error: r.data.error || `HTTP ${r.status}` };
      redraw();
    } finally {
      state.pending.routes--;
    }
  }

  function scheduleAutosave() {
    if (!state.sessionLoaded) return;
    clearTimeout(state.autosaveTimer);
    state.autosaveTimer = setTimeout(async () => {
      state.autosaveTimer = null;
      const r = await api("/api/autosave", { map: state.map });
      if (!r.ok) {
        state.autosaveFailed = true;
        message(`autosave failed: ${r.data.error || r.status}`, "error");
      } else if (state.autosaveFailed) { // the failure is over: say so instead of keeping it
        state.autosaveFailed = false;
        message("autosaved: the server answers again", "ok");
      }
    }, AUTOSAVE_DELAY_MS);
  }

  function showProblems(problems) {
    state.problems = Array.isArray(problems) ? problems : [];
    state.activeProblem = -1;
    const ul = $("problems");
    ul.replaceChildren();
    let errors = 0;
    let warnings = 0;
    state.problems.forEach((p, i) => {
      if (p.severity === "error") errors++;
      else warnings++;
      const li = document.createElement("li");
      li.className = "problem";
      li.dataset.severity = p.severity === "error" ? "error" : "warning";
      li.dataset.path = p.path || "$";
      li.dataset.index = String(i);
      const path = document.createElement("span");
      path.className = "path";
      path.textContent = p.path || "$";
      li.append(path, document.createTextNode(` ${p.message || ""}`));
      li.title = `${p.severity}: click to show it on the map`;
      li.addEventListener("click", () => focusProblem(i));
      ul.append(li);
    });
    const status = $("status");
    status.textContent = `${plural(errors, "error")}, ${plural(warnings, "warning")}`;
    status.className = errors ? "errors" : warnings ? "warnings" : "";
    redraw();
  }

  function problemPlace(p) {
    if (Array.isArray(p.point) && p.point.length === 2) return p.point;
    const el = p.element || {};
    const pts = elementPoints(el.kind, el.index);
    if (!pts.length) return null;
    const sx = pts.reduce((s, q) => s + q[0], 0);
    const sy = pts.reduce((s, q) => s + q[1], 0);
    return [sx / pts.length, sy / pts.length];
  }

  function focusProblem(i) {
    const p = state.problems[i];
    if (!p) return;
    state.activeProblem = i;
    for (const li of $("problems").children) li.classList.toggle("active", li.dataset.index === String(i));
    const place = problemPlace(p);
    if (place) centreOn(place[0], place[1]);
    else redraw();
  }

  // The points of a map element (for markers and centring).
  function elementPoints(kind, index) {
    const m = state.map;
    if (!m) return [];
    const ids = nodeIndexById();
    const pos = (id) => nodePosition(id, ids);
    const groupPoints = (g) => (g ? [...(g.starts || []), ...(g.goals || [])].map(pos).filter(Boolean) : []);
    switch (kind) {
      case "wall": { const w = list("walls")[index]; return w ? [[w[0], w[1]], [w[2], w[3]]] : []; }
      case "node": { const n = list("nodes")[index]; return n ? [n.position] : []; }
      case "edge": { const e = list("edges")[index]; return e ? [pos(e[0]), pos(e[1])].filter(Boolean) : []; }
      case "zone": { const z = list("zones")[index]; return z ? [[z.rect[0], z.rect[1]], [z.rect[2], z.rect[3]]] : []; }
      case "group": return groupPoints(list("groups")[index]);
      case "pedestrian_group": return groupPoints(list("pedestrian_groups")[index]);
      case "route": { const r = list("routes")[index]; return r ? r.map(pos).filter(Boolean) : []; }
      case "bounds": { const b = m.bounds; return Array.isArray(b) && b.length === 4 ? [[b[0], b[1]], [b[2], b[3]]] : []; }
      default: return [];
    }
  }

  // ---------------------------------------------------------------- session

  async function loadSession() {
    const r = await api("/api/session");
    if (!r.ok) {
      $("status").textContent = "no session";
      message(TOKEN ? `could not load the session: ${r.data.error || r.status}`
        : "this page needs the editor's token: open the address that `sgjax edit` printed (it ends in ?token=...)", "error");
      return;
    }
    const s = r.data;
    state.map = s.map;
    state.file = s.file || "";
    state.root = s.root || "";
    state.history = [snapshot()];
    state.historyIndex = 0;
    $("filename").value = state.file;
    document.title = `${s.map && s.map.name ? s.map.name : "map"} - sgjax map editor`;
    const policy = $("play-policy");
    policy.replaceChildren();
    for (const name of s.policies || []) {
      const opt = document.createElement("option");
      opt.value = name;
      opt.textContent = name;
      policy.append(opt);
    }
    if ((s.policies || []).includes("only_local")) policy.value = "only_local";
    fillFamilies(s.families);
    const report = Array.isArray(s.import_report) ? s.import_report : [];
    $("import-report").replaceChildren(...report.map((line) => {
      const li = document.createElement("li");
      li.textContent = line;
      return li;
    }));
    $("import-panel").hidden = report.length === 0;
    syncInputs();
    updateUndoButtons();
    state.sessionLoaded = true;
    if (state.size.w > 10) {
      state.fitted = true;
      fitView();
    }
    refreshPanels();
    message(state.root ? `editing ${state.file} in ${state.root}` : `editing ${state.file}`);
    clearTimeout(state.checkTimer);
    state.checkTimer = null;
    runCheck();
    if (s.autosave && !deepEqual(s.autosave, s.map)) {
      showDialog("restore-dialog", (yes) => {
        if (yes) {
          setMap(s.autosave);
          message("autosave restored (undo goes back to the file)", "ok");
        }
      });
    }
  }

  // ---------------------------------------------------------------- dialogs

  function showDialog(id, done) {
    const dialog = $(id);
    const yes = $(id.replace("-dialog", "-yes"));
    const no = $(id.replace("-dialog", "-no"));
    const close = (answer) => {
      dialog.hidden = true;
      yes.onclick = null;
      no.onclick = null;
      done(answer);
    };
    yes.onclick = () => close(true);
    no.onclick = () => close(false);
    dialog.hidden = false;
    yes.focus();
  }

  const dialogOpen = () => !$("restore-dialog").hidden || !$("overwrite-dialog").hidden;

  // ---------------------------------------------------------------- save and play

  async function save(overwrite = false) {
    if (!state.map) return;
    pushSnapshot();
    const file = $("filename").value.trim();
    if (!file) {
      message("give a file name to save to", "error");
      return;
    }
    state.pending.save++;
    let r;
    try {
      message(`saving ${file}...`);
      r = await api("/api/save", { map: state.map, file, overwrite });
    } finally {
      state.pending.save--;
    }
    if (r.ok) {
      clearTimeout(state.autosaveTimer); // what would be autosaved is saved
      state.autosaveTimer = null;
      message(`saved ${r.data.saved}`, "ok");
      return;
    }
    if (r.status === 409 && !overwrite) {
      $("overwrite-text").textContent = `${file} exists. Overwrite it?`;
      message(r.data.error || `${file} exists`);
      showDialog("overwrite-dialog", (yes) => {
        if (yes) save(true);
        else message("not saved");
      });
      return;
    }
    message(`not saved: ${r.data.error || `HTTP ${r.status}`}`, "error");
    if (Array.isArray(r.data.problems)) showProblems(r.data.problems);
  }

  function intInput(id, fallback) {
    const v = parseInt($(id).value, 10);
    return Number.isFinite(v) && v > 0 ? v : fallback;
  }

  async function play() {
    if (!state.map || state.pending.play) return;
    pushSnapshot();
    stopPlayback();
    const body = {
      map: state.map,
      policy: $("play-policy").value,
      robots: intInput("play-robots", 4),
      episodes: intInput("play-episodes", 64),
      seed: 0,
    };
    const result = $("play-result");
    result.textContent = "running...";
    $("play").disabled = true;
    const started = performance.now();
    const ticker = setInterval(() => {
      const secs = Math.round((performance.now() - started) / 1000);
      result.textContent = state.stopping ? `stopping... ${secs} s` : `running... ${secs} s`;
    }, 1000);
    state.stopping = false;
    state.pending.play++;
    let r;
    try {
      r = await api("/api/play", body);
    } finally {
      clearInterval(ticker);
      state.pending.play--;
      state.stopping = false;
      $("play").disabled = false;
    }
    if (r.status === 409 && r.data.cancelled) {
      result.textContent = r.data.error.replace(/^play: /, "");
      message("play stopped");
      return;
    }
    if (!r.ok) {
      result.textContent = "failed";
      message(`play failed: ${r.data.error || `HTTP ${r.status}`}`, "error");
      if (Array.isArray(r.data.problems)) showProblems(r.data.problems);
      return;
    }
    showMetrics(r.data, body);
    if (r.data.episode) startPlayback(r.data.episode);
  }

  function showMetrics(answer, body) {
    const result = $("play-result");
    result.replaceChildren();
    const caption = document.createElement("p");
    caption.className = "muted";
    const secs = answer.seconds || {};
    caption.textContent = `${body.policy}, ${body.robots} robots, ${body.episodes} episodes` +
      (secs.compile !== undefined ? ` (compile ${fmt(secs.compile, 1)} s, run ${fmt(secs.run, 1)} s)` : "");
    const table = document.createElement("table");
    const head = table.insertRow();
    for (const text of ["metric", "mean ± std"]) {
      const th = document.createElement("th");
      th.textContent = text;
      head.append(th);
    }
    for (const [name, value] of Object.entries(answer.metrics || {})) {
      const row = table.insertRow();
      row.dataset.metric = name;
      row.insertCell().textContent = name;
      const cell = row.insertCell();
      cell.className = "num";
      if (value && typeof value === "object") cell.textContent = `${fmt(value.mean, 3)} ± ${fmt(value.std, 3)}`;
      else cell.textContent = String(value);
    }
    result.append(caption, table);
  }

  function startPlayback(episode) {
    if (!episode || !Array.isArray(episode.frames) || !episode.frames.length) return;
    state.playback = { episode, start: performance.now() };
    const step = () => {
      if (!state.playback || state.playback.episode !== episode) return;
      drawNow();
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }

  function stopPlayback() {
    state.playback = null;
    redraw();
  }

  // Stop: the animation, and a batch under way (the server ends it after its current part).
  async function stop() {
    stopPlayback();
    if (!state.pending.play || state.stopping) return;
    state.stopping = true;
    $("play-result").textContent = "stopping...";
    const r = await api("/api/play/cancel", {});
    if (!r.ok) message(`stop failed: ${r.data.error || r.status}`, "error");
  }

  function playbackFrame() {
    const pb = state.playback;
    if (!pb) return -1;
    const ep = pb.episode;
    const length = Math.min(ep.length || ep.frames.length, ep.frames.length);
    const dt = ep.dt > 0 ? ep.dt : 0.1;
    const hold = Math.round(1 / dt); // one second on the last frame, then again
    const t = Math.floor((performance.now() - pb.start) / 1000 / dt) % (length + hold);
    return Math.min(t, length - 1);
  }

  // ---------------------------------------------------------------- generate

  // The Generate panel: a family's parameters as low / high fields (its default ranges), and
  // the world of a seed drawn by the server (/api/generate) replacing the map (one undo step).
  function fillGenerateFields() {
    const fam = (state.families || []).find((f) => f.name === $("generate-family").value);
    const table = $("generate-parameters");
    table.replaceChildren();
    if (!fam) return;
    const head = document.createElement("tr");
    for (const text of ["parameter", "low", "high", ""]) {
      const th = document.createElement("th");
      th.textContent = text;
      head.append(th);
    }
    table.append(head);
    for (const [name, p] of Object.entries(fam.parameters)) {
      const row = document.createElement("tr");
      const label = document.createElement("td");
      label.textContent = name;
      label.title = `${p.doc} (limits ${p.limits[0]} to ${p.limits[1]} ${p.unit})`;
      row.append(label);
      for (const [i, side] of [[0, "low"], [1, "high"]]) {
        const cell = document.createElement("td");
        const input = document.createElement("input");
        input.type = "number";
        input.step = "any";
        input.value = String(p.default[i]);
        input.dataset.parameter = name;
        input.dataset.side = side;
        input.setAttribute("aria-label", `${name} ${side}`);
        cell.append(input);
        row.append(cell);
      }
      const unit = document.createElement("td");
      unit.textContent = p.unit;
      unit.className = "muted";
      row.append(unit);
      table.append(row);
    }
    $("generate-info").textContent = fam.description;
  }

  function fillFamilies(list) {
    state.families = Array.isArray(list) ? list : [];
    const select = $("generate-family");
    select.replaceChildren();
    for (const fam of state.families) {
      const opt = document.createElement("option");
      opt.value = fam.name;
      opt.textContent = fam.name;
      select.append(opt);
    }
    $("generate-panel").hidden = state.families.length === 0;
    fillGenerateFields();
  }

  function generateRanges() {
    const ranges = {};
    for (const input of $("generate-parameters").querySelectorAll("input[data-parameter]")) {
      const name = input.dataset.parameter;
      ranges[name] = ranges[name] || [null, null];
      ranges[name][input.dataset.side === "low" ? 0 : 1] = Number(input.value);
    }
    return ranges;
  }

  async function generateWorld() {
    if (state.pending.generate > 0) return;
    const seed = Number($("generate-seed").value);
    if (!Number.isInteger(seed) || seed < 0) {
      message("generate: the seed must be a whole number, 0 or more", "error");
      return;
    }
    state.pending.generate++;
    $("generate").disabled = true;
    $("generate-info").textContent = "drawing (the first world of a family compiles its generator)...";
    try {
      const family = $("generate-family").value;
      const r = await api("/api/generate", { family, seed, ranges: generateRanges() });
      if (!r.ok) {
        $("generate-info").textContent = "";
        message(`generate: ${r.data.error || r.status}`, "error");
        return;
      }
      setMap(r.data.map);
      fitView();
      const values = Object.entries(r.data.values).map(([k, v]) => `${k} ${v.toFixed(2)}`).join(", ");
      $("generate-info").textContent = `${family} world ${r.data.seed}: ${values}`;
      message(r.data.valid ? `drew ${family} world ${r.data.seed} (undo brings the map back)`
        : `drew ${family} world ${r.data.seed}, which fails the family's checks (see Problems)`,
        r.data.valid ? "ok" : "error");
    } finally {
      state.pending.generate--;
      $("generate").disabled = false;
    }
  }

  // ---------------------------------------------------------------- panels

  function syncInputs() {
    const m = state.map;
    if (!m) return;
    $("map-name").value = m.name ?? "";
    $("map-description").value = m.description ?? "";
    const b = Array.isArray(m.bounds) ? m.bounds : [];
    ["xmin", "ymin", "xmax", "ymax"].forEach((k, i) => {
      $(`bounds-${k}`).value = b[i] ?? "";
    });
  }

  function currentGroups() {
    return list(state.group.kind);
  }

  function refreshPanels() {
    if (!state.map) return;
    // groups
    const groups = currentGroups();
    if (state.group.index >= groups.length) state.group.index = Math.max(0, groups.length - 1);
    const select = $("group-index");
    select.replaceChildren();
    if (!groups.length) {
      const opt = document.createElement("option");
      opt.value = "-1";
      opt.textContent = "none yet";
      select.append(opt);
    }
    groups.forEach((g, i) => {
      const opt = document.createElement("option");
      opt.value = String(i);
      opt.textContent = `${i}: ${(g.starts || []).length} starts, ${(g.goals || []).length} goals`;
      select.append(opt);
    });
    select.value = groups.length ? String(state.group.index) : "-1";
    $("group-kind").value = state.group.kind;
    $("group-phase").textContent = `Phase: ${state.group.phase}`;
    $("group-phase").dataset.phase = state.group.phase;
    const g = groups[state.group.index];
    const ids = (values) => {
      const v = values || [];
      return v.length > 12 ? `${v.slice(0, 12).join(", ")}, ... (${v.length})` : v.join(", ");
    };
    $("group-info").textContent = g
      ? `starts: ${ids(g.starts) || "none"}; goals: ${ids(g.goals) || "none"}`
      : "With the group tool, clicking a node makes a group.";
    // selection
    $("selection-info").textContent = selectionText() || "Nothing selected: click a node, wall, edge or zone with Select (V).";
    showSelectionFields();
    // tools
    for (const b of document.querySelectorAll("[data-tool]")) b.classList.toggle("active", b.dataset.tool === state.tool);
    updateUndoButtons();
  }

  function selectionText() {
    const s = state.selection;
    if (!s) return "";
    if (s.kind === "node") {
      const n = list("nodes")[s.index];
      return n ? `node ${n.id} at (${fmt(n.position[0])}, ${fmt(n.position[1])})` : "";
    }
    if (s.kind === "wall") {
      const w = list("walls")[s.index];
      return w ? `wall ${s.index}: (${fmt(w[0])}, ${fmt(w[1])}) - (${fmt(w[2])}, ${fmt(w[3])}), ${fmt(Math.hypot(w[2] - w[0], w[3] - w[1]))} m` : "";
    }
    if (s.kind === "edge") {
      const e = list("edges")[s.index];
      return e ? `edge ${s.index}: ${e[0]} - ${e[1]}` : "";
    }
    if (s.kind === "zone") {
      const z = list("zones")[s.index];
      return z ? `zone ${s.index} "${z.name}": ${z.rect.map((v) => fmt(v)).join(", ")}` : "";
    }
    return "";
  }

  // ---------------------------------------------------------------- the selection's exact values

  // The fields of the selected element: {key, label, value, text?, integer?, set(value) ->
  // error string or nothing}. Each edits that element only; a wall end moves every wall end at
  // the same place, as dragging it does.
  function selectionFields() {
    const s = state.selection;
    if (!s) return [];
    if (s.kind === "node") {
      const n = list("nodes")[s.index];
      if (!n) return [];
      return [
        { key: "id", label: "id", value: n.id, integer: true, set: (v) => renameNode(n, v) },
        { key: "x", label: "x (m)", value: n.position[0], set: (v) => { n.position[0] = v; } },
        { key: "y", label: "y (m)", value: n.position[1], set: (v) => { n.position[1] = v; } },
      ];
    }
    if (s.kind === "wall") {
      const w = list("walls")[s.index];
      if (!w) return [];
      const end = (k, axis, label) => ({
        key: `${label}`, label: `${label} (m)`, value: w[k + axis],
        set: (v) => { for (const [i, kk] of endsAt(w[k], w[k + 1])) list("walls")[i][kk + axis] = v; },
      });
      return [end(0, 0, "x1"), end(0, 1, "y1"), end(2, 0, "x2"), end(2, 1, "y2")];
    }
    if (s.kind === "zone") {
      const z = list("zones")[s.index];
      if (!z) return [];
      const corner = (j, label) => ({
        key: label, label: `${label} (m)`, value: z.rect[j],
        set: (v) => {
          const r = [...z.rect];
          r[j] = v;
          z.rect = [Math.min(r[0], r[2]), Math.min(r[1], r[3]), Math.max(r[0], r[2]), Math.max(r[1], r[3])];
        },
      });
      return [
        { key: "name", label: "name", value: z.name, text: true, set: (v) => {
          if (!v.trim()) return "a zone needs a name";
          z.name = v.trim();
        } },
        corner(0, "x min"), corner(1, "y min"), corner(2, "x max"), corner(3, "y max"),
      ];
    }
    return [];
  }

  // Rebuild the fields when another element is selected; otherwise refresh the values of the
  // fields not being typed in.
  function showSelectionFields() {
    const box = $("selection-fields");
    const s = state.selection;
    const fields = selectionFields();
    const id = s && fields.length ? `${s.kind}:${s.index}` : "";
    if (id !== state.fieldsFor || box.children.length !== fields.length) {
      state.fieldsFor = id;
      box.replaceChildren(...fields.map(fieldElement));
      return;
    }
    fields.forEach((f, i) => {
      const input = box.children[i].querySelector("input");
      if (input !== document.activeElement) input.value = f.text ? f.value : String(f.value);
    });
  }

  function fieldElement(f) {
    const label = document.createElement("label");
    label.className = f.text ? "wide" : "";
    const input = document.createElement("input");
    input.id = `sel-${f.key.replace(" ", "-")}`;
    input.type = f.text ? "text" : "number";
    if (!f.text) input.step = f.integer ? "1" : "any";
    input.spellcheck = false;
    input.value = f.text ? f.value : String(f.value);
    input.addEventListener("change", () => {
      const field = selectionFields().find((g) => g.key === f.key);
      if (!field) return;
      const raw = input.value.trim();
      let value = input.value;
      if (!field.text) {
        value = raw === "" ? NaN : field.integer ? Number(raw) : round6(Number(raw));
        if (!Number.isFinite(value) || (field.integer && !Number.isInteger(value))) {
          // a number field holds "" for text it cannot read: say what is expected, not ""
          const got = raw === "" ? "" : `, got ${JSON.stringify(raw)}`;
          message(`${field.label}: expected ${field.integer ? "an integer" : "a number"}${got}`, "error");
          input.value = String(field.value);
          return;
        }
      }
      const error = field.set(value);
      if (error) {
        message(error, "error");
        input.value = field.text ? field.value : String(field.value);
        return;
      }
      changed();
    });
    label.append(document.createTextNode(`${f.label} `), input);
    return label;
  }

  // Give node `node` the id `id` (unused), in every edge, group and route that names it.
  function renameNode(node, id) {
    const old = node.id;
    if (id === old) return undefined;
    if (list("nodes").some((n) => n.id === id)) return `node id ${id} is taken`;
    const swap = (v) => (v === old ? id : v);
    node.id = id;
    const m = state.map;
    if (Array.isArray(m.edges)) m.edges = m.edges.map((e) => e.map(swap));
    for (const key of ["groups", "pedestrian_groups"]) {
      for (const g of list(key)) {
        if (Array.isArray(g.starts)) g.starts = g.starts.map(swap);
        if (Array.isArray(g.goals)) g.goals = g.goals.map(swap);
      }
    }
    if (Array.isArray(m.routes)) m.routes = m.routes.map((r) => r.map(swap));
    if (state.edgeFrom === old) state.edgeFrom = id;
    return undefined;
  }

  function setTool(tool) {
    if (!Object.values(TOOLS).includes(tool)) return;
    state.tool = tool;
    state.chain = null;
    state.edgeFrom = null;
    state.drag = null;
    canvas.style.cursor = tool === "select" ? "default" : "crosshair";
    refreshPanels();
    redraw();
  }

  // ---------------------------------------------------------------- snapping and hit tests

  function gridStep() {
    const v = parseFloat($("grid").value);
    return Number.isFinite(v) && v > 0 ? v : 0.5;
  }

  // A world point for screen point (px, py): a wall end or node within SNAP_PX when `attract`,
  // else the grid (when Snap is on), else millimetres. `skip(kind, i, end)` leaves out points
  // being dragged.
  function snapPoint(px, py, attract = true, skip = () => false) {
    const [wx, wy] = screenToWorld(px, py);
    if (attract) {
      let best = null;
      let bestD = SNAP_PX;
      const consider = (x, y) => {
        const [sx, sy] = worldToScreen(x, y);
        const d = Math.hypot(sx - px, sy - py);
        if (d < bestD) { bestD = d; best = { x, y, snapped: true }; }
      };
      list("walls").forEach((w, i) => {
        if (!skip("wall", i, 0)) consider(w[0], w[1]);
        if (!skip("wall", i, 2)) consider(w[2], w[3]);
      });
      list("nodes").forEach((n, i) => { if (!skip("node", i)) consider(n.position[0], n.position[1]); });
      if (best) return best;
    }
    if ($("snap").checked) {
      const step = gridStep();
      return { x: round6(Math.round(wx / step) * step), y: round6(Math.round(wy / step) * step), snapped: false };
    }
    return { x: Math.round(wx * 1000) / 1000 + 0, y: Math.round(wy * 1000) / 1000 + 0, snapped: false };
  }

  function hitNode(px, py, tol = HIT_PX) {
    let best = -1;
    let bestD = tol;
    list("nodes").forEach((n, i) => {
      const [sx, sy] = worldToScreen(n.position[0], n.position[1]);
      const d = Math.hypot(sx - px, sy - py);
      if (d <= bestD) { bestD = d; best = i; }
    });
    return best;
  }

  // The wall end nearest (px, py) within tol, with every wall end at that place.
  function hitWallEnd(px, py, tol = HIT_PX) {
    let best = null;
    let bestD = tol;
    list("walls").forEach((w) => {
      for (const k of [0, 2]) {
        const [sx, sy] = worldToScreen(w[k], w[k + 1]);
        const d = Math.hypot(sx - px, sy - py);
        if (d <= bestD) { bestD = d; best = { x: w[k], y: w[k + 1] }; }
      }
    });
    if (!best) return null;
    return { x: best.x, y: best.y, refs: endsAt(best.x, best.y) };
  }

  function endsAt(x, y) {
    const refs = [];
    list("walls").forEach((w, i) => {
      for (const k of [0, 2]) if (Math.abs(w[k] - x) < 1e-9 && Math.abs(w[k + 1] - y) < 1e-9) refs.push([i, k]);
    });
    return refs;
  }

  function hitWall(px, py, tol = 6) {
    let best = -1;
    let bestD = tol;
    list("walls").forEach((w, i) => {
      const a = worldToScreen(w[0], w[1]);
      const b = worldToScreen(w[2], w[3]);
      const { d } = segmentDistance(px, py, a[0], a[1], b[0], b[1]);
      if (d <= bestD) { bestD = d; best = i; }
    });
    return best;
  }

  function hitEdge(px, py, tol = 5) {
    const ids = nodeIndexById();
    let best = -1;
    let bestD = tol;
    list("edges").forEach((e, i) => {
      const p = nodePosition(e[0], ids);
      const q = nodePosition(e[1], ids);
      if (!p || !q) return;
      const a = worldToScreen(p[0], p[1]);
      const b = worldToScreen(q[0], q[1]);
      const { d } = segmentDistance(px, py, a[0], a[1], b[0], b[1]);
      if (d <= bestD) { bestD = d; best = i; }
    });
    return best;
  }

  // A zone corner within tol: {index, cx: 0|2, cy: 1|3}.
  function hitZoneCorner(px, py, tol = HIT_PX) {
    let best = null;
    let bestD = tol;
    list("zones").forEach((z, i) => {
      for (const cx of [0, 2]) {
        for (const cy of [1, 3]) {
          const [sx, sy] = worldToScreen(z.rect[cx], z.rect[cy]);
          const d = Math.hypot(sx - px, sy - py);
          if (d <= bestD) { bestD = d; best = { index: i, cx, cy }; }
        }
      }
    });
    return best;
  }

  // The smallest zone containing (px, py), or one whose border is within 5 px.
  function hitZone(px, py) {
    const [wx, wy] = screenToWorld(px, py);
    const tol = 5 / state.view.scale;
    let best = -1;
    let bestArea = Infinity;
    list("zones").forEach((z, i) => {
      const [x0, y0, x1, y1] = z.rect;
      const xa = Math.min(x0, x1), xb = Math.max(x0, x1), ya = Math.min(y0, y1), yb = Math.max(y0, y1);
      if (wx >= xa - tol && wx <= xb + tol && wy >= ya - tol && wy <= yb + tol) {
        const area = (xb - xa) * (yb - ya);
        if (area < bestArea) { bestArea = area; best = i; }
      }
    });
    return best;
  }

  // What a click at (px, py) would pick, in order: node, wall, edge, zone.
  function pick(px, py) {
    let i = hitNode(px, py);
    if (i >= 0) return { kind: "node", index: i };
    i = hitWall(px, py);
    if (i >= 0) return { kind: "wall", index: i };
    i = hitEdge(px, py);
    if (i >= 0) return { kind: "edge", index: i };
    i = hitZone(px, py);
    if (i >= 0) return { kind: "zone", index: i };
    return null;
  }

  // ---------------------------------------------------------------- edits

  function nextNodeId() {
    let max = -1;
    for (const n of list("nodes")) if (Number.isInteger(n.id) && n.id > max) max = n.id;
    return max + 1;
  }

  function ensureList(key) {
    if (!Array.isArray(state.map[key])) state.map[key] = [];
    return state.map[key];
  }

  function deleteNode(index) {
    const m = state.map;
    const node = list("nodes")[index];
    if (!node) return;
    const id = node.id;
    m.nodes.splice(index, 1);
    if (Array.isArray(m.edges)) m.edges = m.edges.filter((e) => e[0] !== id && e[1] !== id);
    for (const key of ["groups", "pedestrian_groups"]) {
      if (!Array.isArray(m[key])) continue;
      for (const g of m[key]) {
        if (Array.isArray(g.starts)) g.starts = g.starts.filter((v) => v !== id);
        if (Array.isArray(g.goals)) g.goals = g.goals.filter((v) => v !== id);
      }
      m[key] = m[key].filter((g) => (g.starts || []).length + (g.goals || []).length > 0);
    }
    if (Array.isArray(m.routes)) {
      m.routes = m.routes
        .filter((r) => r.length && r[0] !== id && r[r.length - 1] !== id)
        .map((r) => r.filter((v) => v !== id))
        .filter((r) => r.length >= 2);
    }
    if (state.edgeFrom === id) state.edgeFrom = null;
  }

  function deleteElement(sel) {
    if (!sel || !state.map) return false;
    const arrays = { wall: "walls", edge: "edges", zone: "zones" };
    if (sel.kind === "node") {
      if (!list("nodes")[sel.index]) return false;
      deleteNode(sel.index);
    } else if (arrays[sel.kind]) {
      const items = list(arrays[sel.kind]);
      if (!items[sel.index]) return false;
      items.splice(sel.index, 1);
    } else {
      return false;
    }
    state.selection = null;
    changed();
    return true;
  }

  function splitWall(index, px, py) {
    const w = list("walls")[index];
    if (!w) return;
    const [wx, wy] = screenToWorld(px, py);
    const q = segmentDistance(wx, wy, w[0], w[1], w[2], w[3]);
    let x = q.x;
    let y = q.y;
    if ($("snap").checked) { // the grid point, when it lies on the wall
      const step = gridStep();
      const gx = round6(Math.round(x / step) * step);
      const gy = round6(Math.round(y / step) * step);
      const g = segmentDistance(gx, gy, w[0], w[1], w[2], w[3]);
      if (g.d < 1e-9 && g.t > 0 && g.t < 1) { x = gx; y = gy; }
    }
    x = round6(x);
    y = round6(y);
    const len = Math.hypot(w[2] - w[0], w[3] - w[1]);
    if (Math.hypot(x - w[0], y - w[1]) < 1e-6 * Math.max(1, len) || Math.hypot(x - w[2], y - w[3]) < 1e-6 * Math.max(1, len)) {
      message("split: click inside the wall, not at its end");
      return;
    }
    state.map.walls.splice(index, 1, [w[0], w[1], x, y], [x, y, w[2], w[3]]);
    state.selection = null;
    changed();
  }

  // The node ids of the current group's current phase (starts or goals), made if missing.
  function phaseIds() {
    const groups = ensureList(state.group.kind);
    if (state.group.index >= groups.length || state.group.index < 0) {
      groups.push({ starts: [], goals: [] });
      state.group.index = groups.length - 1;
    }
    const g = groups[state.group.index];
    if (!Array.isArray(g[state.group.phase])) g[state.group.phase] = [];
    return g[state.group.phase];
  }

  function toggleInGroup(nodeIndex) {
    const node = list("nodes")[nodeIndex];
    if (!node) return;
    const ids = phaseIds();
    const at = ids.indexOf(node.id);
    if (at >= 0) ids.splice(at, 1);
    else ids.push(node.id);
    changed();
  }

  function newGroup() {
    if (!state.map) return;
    const groups = ensureList(state.group.kind);
    groups.push({ starts: [], goals: [] });
    state.group.index = groups.length - 1;
    state.group.phase = "starts";
    changed();
  }

  function boundsToContent() {
    const box = contentBox(false);
    if (!box) {
      message("nothing drawn yet: bounds unchanged");
      return;
    }
    state.map.bounds = [round6(box[0] - 1), round6(box[1] - 1), round6(box[2] + 1), round6(box[3] + 1)];
    syncInputs();
    changed();
  }

  // ---------------------------------------------------------------- pointer input

  function eventPoint(e) {
    const rect = canvas.getBoundingClientRect();
    return [e.clientX - rect.left, e.clientY - rect.top];
  }

  canvas.addEventListener("contextmenu", (e) => e.preventDefault());

  canvas.addEventListener("pointerdown", (e) => {
    if (!state.map) return;
    canvas.focus({ preventScroll: true });
    const [px, py] = eventPoint(e);
    if (e.button === 1 || (e.button === 0 && state.spaceDown)) {
      e.preventDefault();
      beginPan(e, px, py);
      return;
    }
    if (e.button === 2) { // right click ends what is under way
      state.chain = null;
      state.edgeFrom = null;
      redraw();
      return;
    }
    if (e.button !== 0) return;
    const tool = state.tool;
    if (tool === "select") selectDown(e, px, py);
    else if (tool === "wall") wallDown(px, py);
    else if (tool === "node") nodeDown(px, py);
    else if (tool === "edge") edgeDown(e, px, py);
    else if (tool === "group") {
      const i = hitNode(px, py);
      if (i >= 0) toggleInGroup(i);
      else { // a box: every node in it joins the group's current phase
        const [wx, wy] = screenToWorld(px, py);
        state.drag = { type: "groupBox", start: { x: wx, y: wy }, end: { x: wx, y: wy } };
        canvas.setPointerCapture(e.pointerId);
      }
    } else if (tool === "zone") {
      const p = snapPoint(px, py);
      state.drag = { type: "newZone", start: p, end: p };
      canvas.setPointerCapture(e.pointerId);
    } else if (tool === "split") {
      const i = hitWall(px, py);
      if (i >= 0) splitWall(i, px, py);
    } else if (tool === "delete") {
      deleteElement(pick(px, py));
    }
    redraw();
  });

  function beginPan(e, px, py) {
    state.drag = { type: "pan", px, py, cx: state.view.cx, cy: state.view.cy, moved: false };
    canvas.setPointerCapture(e.pointerId);
    canvas.style.cursor = "grabbing";
  }

  function selectDown(e, px, py) {
    const node = hitNode(px, py);
    if (node >= 0) {
      state.selection = { kind: "node", index: node };
      const n = list("nodes")[node];
      state.drag = { type: "node", index: node, orig: [...n.position], moved: false, px, py };
    } else {
      const end = hitWallEnd(px, py);
      const corner = end ? null : hitZoneCorner(px, py);
      if (end) {
        state.selection = { kind: "wall", index: end.refs[0][0] };
        state.drag = { type: "wallEnd", refs: end.refs, moved: false, px, py };
      } else if (corner) {
        state.selection = { kind: "zone", index: corner.index };
        state.drag = { type: "zoneCorner", ...corner, moved: false, px, py };
      } else {
        const sel = pick(px, py);
        state.selection = sel;
        if (sel && sel.kind === "wall") {
          const w = list("walls")[sel.index];
          state.drag = {
            type: "wall", index: sel.index, orig: [...w], moved: false, px, py,
            a: endsAt(w[0], w[1]), b: endsAt(w[2], w[3]),
          };
        } else if (sel && sel.kind === "zone") {
          state.drag = { type: "zone", index: sel.index, orig: [...list("zones")[sel.index].rect], moved: false, px, py };
        } else if (!sel) {
          beginPan(e, px, py);
          return;
        }
      }
    }
    if (state.drag) canvas.setPointerCapture(e.pointerId);
    refreshPanels();
  }

  function wallDown(px, py) {
    const p = snapPoint(px, py);
    if (!state.chain) {
      state.chain = { x: p.x, y: p.y };
      return;
    }
    if (Math.abs(p.x - state.chain.x) < 1e-9 && Math.abs(p.y - state.chain.y) < 1e-9) return; // a double click
    ensureList("walls").push([state.chain.x, state.chain.y, p.x, p.y]);
    state.chain = { x: p.x, y: p.y };
    changed();
  }

  function nodeDown(px, py) {
    const existing = hitNode(px, py);
    if (existing >= 0) {
      state.selection = { kind: "node", index: existing };
      refreshPanels();
      return;
    }
    const p = snapPoint(px, py, false);
    const nodes = ensureList("nodes");
    nodes.push({ id: nextNodeId(), position: [p.x, p.y] });
    state.selection = { kind: "node", index: nodes.length - 1 };
    changed();
  }

  // The edge tool: press on a node and drag through others to join the run in order (one undo
  // step), or click one node and then another.
  function edgeDown(e, px, py) {
    const i = hitNode(px, py);
    if (i < 0) {
      state.edgeFrom = null;
      return;
    }
    state.drag = { type: "edgeRun", last: list("nodes")[i].id, added: 0, moved: false, px, py };
    canvas.setPointerCapture(e.pointerId);
  }

  function edgeClick(id) {
    if (state.edgeFrom === null || state.edgeFrom === id) {
      state.edgeFrom = id;
      redraw();
      return;
    }
    const a = state.edgeFrom;
    state.edgeFrom = null;
    if (addEdge(a, id)) changed();
    else redraw();
  }

  // Join nodes a and b (ids) unless they are joined already; whether an edge was added.
  function addEdge(a, b) {
    const edges = ensureList("edges");
    if (edges.some((e) => (e[0] === a && e[1] === b) || (e[0] === b && e[1] === a))) {
      message(`edge ${a} - ${b} exists`);
      return false;
    }
    edges.push([a, b]);
    state.selection = { kind: "edge", index: edges.length - 1 };
    return true;
  }

  function nodesInBox(a, b) {
    const [x0, x1] = [Math.min(a.x, b.x), Math.max(a.x, b.x)];
    const [y0, y1] = [Math.min(a.y, b.y), Math.max(a.y, b.y)];
    return list("nodes").filter((n) => n.position[0] >= x0 && n.position[0] <= x1 &&
      n.position[1] >= y0 && n.position[1] <= y1).map((n) => n.id);
  }

  function addToGroup(ids) {
    const phase = phaseIds();
    const added = ids.filter((id) => !phase.includes(id));
    phase.push(...added);
    message(`${plural(added.length, "node")} added to group ${state.group.index}'s ${state.group.phase}`);
    if (added.length) changed();
  }

  canvas.addEventListener("pointermove", (e) => {
    const [px, py] = eventPoint(e);
    const [wx, wy] = screenToWorld(px, py);
    state.cursor = { x: wx, y: wy, px, py };
    $("coords").textContent = `x ${fmt(wx)}  y ${fmt(wy)} m`;
    const d = state.drag;
    if (!d) {
      if (["select", "delete", "edge", "group", "split"].includes(state.tool)) {
        const h = state.tool === "group" || state.tool === "edge" ? (hitNode(px, py) >= 0 ? { kind: "node", index: hitNode(px, py) } : null)
          : state.tool === "split" ? (hitWall(px, py) >= 0 ? { kind: "wall", index: hitWall(px, py) } : null)
            : pick(px, py);
        state.hover = h;
      } else {
        state.hover = null;
      }
      redraw();
      return;
    }
    if (Math.hypot(px - d.px, py - d.py) > 2) d.moved = true;
    if (d.type === "pan") {
      state.view.cx = d.cx - (px - d.px) / state.view.scale;
      state.view.cy = d.cy + (py - d.py) / state.view.scale;
    } else if (d.type === "node" && d.moved) {
      const p = snapPoint(px, py, false);
      list("nodes")[d.index].position = [p.x, p.y];
    } else if (d.type === "wallEnd" && d.moved) {
      const moving = new Set(d.refs.map(([i, k]) => `${i}:${k}`));
      const p = snapPoint(px, py, true, (kind, i, k) => kind === "wall" && moving.has(`${i}:${k}`));
      for (const [i, k] of d.refs) { list("walls")[i][k] = p.x; list("walls")[i][k + 1] = p.y; }
    } else if (d.type === "wall" && d.moved) {
      const [dx, dy] = snappedDelta(px, py, d);
      for (const [i, k] of d.a) { list("walls")[i][k] = round6(d.orig[0] + dx); list("walls")[i][k + 1] = round6(d.orig[1] + dy); }
      for (const [i, k] of d.b) { list("walls")[i][k] = round6(d.orig[2] + dx); list("walls")[i][k + 1] = round6(d.orig[3] + dy); }
    } else if (d.type === "zone" && d.moved) {
      const [dx, dy] = snappedDelta(px, py, d);
      const o = d.orig;
      list("zones")[d.index].rect = [round6(o[0] + dx), round6(o[1] + dy), round6(o[2] + dx), round6(o[3] + dy)];
    } else if (d.type === "zoneCorner" && d.moved) {
      const p = snapPoint(px, py);
      const rect = list("zones")[d.index].rect;
      rect[d.cx] = p.x;
      rect[d.cy] = p.y;
    } else if (d.type === "newZone") {
      d.end = snapPoint(px, py);
    } else if (d.type === "groupBox") {
      d.end = { x: wx, y: wy };
    } else if (d.type === "edgeRun" && d.moved) {
      const j = hitNode(px, py);
      const id = j >= 0 ? list("nodes")[j].id : null;
      if (id !== null && id !== d.last) {
        if (addEdge(d.last, id)) {
          d.added++;
          changed(false); // one undo step for the run, when it ends
        }
        d.last = id;
      }
    }
    redraw();
  });

  // A drag's displacement in world metres, in grid steps when Snap is on.
  function snappedDelta(px, py, d) {
    let dx = (px - d.px) / state.view.scale;
    let dy = -(py - d.py) / state.view.scale;
    if ($("snap").checked) {
      const step = gridStep();
      dx = Math.round(dx / step) * step;
      dy = Math.round(dy / step) * step;
    }
    return [dx, dy];
  }

  function endDrag(e) {
    const d = state.drag;
    if (!d) return;
    state.drag = null;
    if (canvas.hasPointerCapture && canvas.hasPointerCapture(e.pointerId)) canvas.releasePointerCapture(e.pointerId);
    canvas.style.cursor = state.tool === "select" ? "default" : "crosshair";
    if (d.type === "pan") {
      if (!d.moved && state.tool === "select" && !state.spaceDown) { state.selection = null; refreshPanels(); }
      redraw();
      return;
    }
    if (d.type === "edgeRun") {
      if (d.added) {
        state.edgeFrom = null;
        changed();
      } else {
        edgeClick(d.last);
      }
      return;
    }
    if (d.type === "groupBox") {
      addToGroup(nodesInBox(d.start, d.end));
      redraw();
      return;
    }
    if (d.type === "newZone") {
      const [x0, x1] = [Math.min(d.start.x, d.end.x), Math.max(d.start.x, d.end.x)];
      const [y0, y1] = [Math.min(d.start.y, d.end.y), Math.max(d.start.y, d.end.y)];
      if (x1 - x0 > 1e-9 && y1 - y0 > 1e-9) {
        const name = $("zone-name").value.trim() || "zone";
        const zones = ensureList("zones");
        zones.push({ name, rect: [x0, y0, x1, y1] });
        state.selection = { kind: "zone", index: zones.length - 1 };
        changed();
      } else {
        redraw();
      }
      return;
    }
    if (d.type === "zoneCorner") { // keep xmin < xmax and ymin < ymax
      const r = list("zones")[d.index].rect;
      list("zones")[d.index].rect = [Math.min(r[0], r[2]), Math.min(r[1], r[3]), Math.max(r[0], r[2]), Math.max(r[1], r[3])];
    }
    if (d.moved) changed();
    else redraw();
  }

  canvas.addEventListener("pointerup", endDrag);
  canvas.addEventListener("pointercancel", endDrag);
  canvas.addEventListener("pointerleave", () => {
    if (!state.drag) {
      state.cursor = null;
      state.hover = null;
      redraw();
    }
  });

  canvas.addEventListener("dblclick", (e) => {
    e.preventDefault();
    if (state.tool === "wall") {
      state.chain = null;
      redraw();
    }
  });

  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const [px, py] = eventPoint(e);
    const delta = e.deltaMode === 1 ? e.deltaY * 16 : e.deltaMode === 2 ? e.deltaY * 400 : e.deltaY;
    zoomAt(px, py, Math.exp(-delta * 0.0015));
  }, { passive: false });

  // ---------------------------------------------------------------- keyboard

  const typing = (el) => el && (el.tagName === "INPUT" || el.tagName === "TEXTAREA" || el.tagName === "SELECT" || el.isContentEditable);

  document.addEventListener("keydown", (e) => {
    const ctrl = e.ctrlKey || e.metaKey;
    const key = e.key.length === 1 ? e.key.toLowerCase() : e.key;
    if (ctrl && key === "s") {
      e.preventDefault();
      if (!dialogOpen()) save(false);
      return;
    }
    if (dialogOpen()) {
      if (key === "Escape") {
        for (const id of ["restore-no", "overwrite-no"]) if (!$(id.replace("-no", "-dialog")).hidden) $(id).click();
      }
      return;
    }
    if (typing(e.target)) { // the field's own keys (its own undo too), but Escape and Enter
      if (key === "Escape" || (key === "Enter" && e.target.tagName === "INPUT")) {
        e.preventDefault();
        e.target.blur(); // applies the field (its change event)
        canvas.focus({ preventScroll: true });
      }
      return;
    }
    if (ctrl && key === "z") {
      e.preventDefault();
      if (e.shiftKey) redo(); else undo();
      return;
    }
    if (ctrl && key === "y") {
      e.preventDefault();
      redo();
      return;
    }
    if (ctrl || e.altKey) return;
    if (key === " ") {
      e.preventDefault();
      state.spaceDown = true;
      canvas.style.cursor = "grab";
      return;
    }
    if (key === "Escape") {
      state.chain = null;
      state.edgeFrom = null;
      state.selection = null;
      if (state.drag && state.drag.type === "newZone") state.drag = null;
      refreshPanels();
      redraw();
      return;
    }
    if (key === "Delete" || key === "Backspace") {
      e.preventDefault();
      deleteElement(state.selection);
      return;
    }
    if (key === "f") {
      fitView();
      return;
    }
    if (TOOLS[key]) {
      e.preventDefault();
      setTool(TOOLS[key]);
    }
  });

  document.addEventListener("keyup", (e) => {
    if (e.key === " ") {
      state.spaceDown = false;
      canvas.style.cursor = state.tool === "select" ? "default" : "crosshair";
    }
  });

  window.addEventListener("blur", () => { state.spaceDown = false; });

  // ---------------------------------------------------------------- panel inputs

  for (const b of document.querySelectorAll("[data-tool]")) b.addEventListener("click", () => setTool(b.dataset.tool));
  $("undo").addEventListener("click", undo);
  $("redo").addEventListener("click", redo);
  $("fit").addEventListener("click", fitView);
  $("save").addEventListener("click", () => save(false));
  $("play").addEventListener("click", play);
  $("play-stop").addEventListener("click", stop);
  $("generate").addEventListener("click", generateWorld);
  $("generate-next").addEventListener("click", () => {
    $("generate-seed").value = String(Math.max(0, Math.floor(Number($("generate-seed").value) || 0)) + 1);
    generateWorld();
  });
  $("generate-family").addEventListener("change", fillGenerateFields);
  $("bounds-fit").addEventListener("click", () => { if (state.map) boundsToContent(); });
  $("group-new").addEventListener("click", newGroup);
  $("group-phase").addEventListener("click", () => {
    state.group.phase = state.group.phase === "starts" ? "goals" : "starts";
    refreshPanels();
    redraw();
  });
  $("group-kind").addEventListener("change", () => {
    state.group.kind = $("group-kind").value;
    state.group.index = 0;
    refreshPanels();
    redraw();
  });
  $("group-index").addEventListener("change", () => {
    const v = parseInt($("group-index").value, 10);
    state.group.index = Number.isFinite(v) && v >= 0 ? v : 0;
    refreshPanels();
    redraw();
  });
  $("routes").addEventListener("change", () => {
    if ($("routes").checked && state.map) runRoutes();
    else { state.routes = null; redraw(); }
  });
  $("snap").addEventListener("change", redraw);
  $("grid").addEventListener("input", redraw);

  // Text fields change the map as you type (checked after each pause) and make one undo step
  // when they lose focus.
  function bindField(id, apply) {
    const el = $(id);
    el.addEventListener("input", () => {
      if (!state.map) return;
      if (apply(el.value) !== false) changed(false);
    });
    el.addEventListener("change", () => { if (state.map) pushSnapshot(); });
  }
  bindField("map-name", (v) => { state.map.name = v; });
  bindField("map-description", (v) => { state.map.description = v; });
  ["xmin", "ymin", "xmax", "ymax"].forEach((k, i) => {
    bindField(`bounds-${k}`, (v) => {
      const x = parseFloat(v);
      if (!Number.isFinite(x)) return false;
      if (!Array.isArray(state.map.bounds) || state.map.bounds.length !== 4) state.map.bounds = [0, 0, 1, 1];
      state.map.bounds[i] = x;
      return true;
    });
  });

  // ---------------------------------------------------------------- drawing

  function redraw() {
    if (state.redrawQueued) return;
    state.redrawQueued = true;
    requestAnimationFrame(() => {
      state.redrawQueued = false;
      drawNow();
    });
  }

  function drawNow() {
    const dpr = window.devicePixelRatio || 1;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, state.size.w, state.size.h);
    ctx.fillStyle = "#fbfbfc";
    ctx.fillRect(0, 0, state.size.w, state.size.h);
    if (!state.map) return;
    drawGrid();
    drawBounds();
    drawZones();
    drawEdges();
    if ($("routes").checked) drawRoutes();
    drawWalls();
    drawNodes();
    drawProblems();
    drawHover();
    drawToolPreview();
    if (state.playback) drawPlayback();
  }

  function line(x1, y1, x2, y2) {
    const a = worldToScreen(x1, y1);
    const b = worldToScreen(x2, y2);
    ctx.moveTo(a[0], a[1]);
    ctx.lineTo(b[0], b[1]);
  }

  function drawGrid() {
    const [x0, y1] = screenToWorld(0, 0);
    const [x1, y0] = screenToWorld(state.size.w, state.size.h);
    const scale = state.view.scale;
    const metre = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000].find((s) => s * scale >= 14) || 1000;
    const step = gridStep();
    const lines = (s, color) => {
      if (s * scale < 6) return;
      ctx.beginPath();
      for (let x = Math.ceil(x0 / s) * s; x <= x1; x += s) line(x, y0, x, y1);
      for (let y = Math.ceil(y0 / s) * s; y <= y1; y += s) line(x0, y, x1, y);
      ctx.strokeStyle = color;
      ctx.lineWidth = 1;
      ctx.stroke();
    };
    if ($("snap").checked && step < metre) lines(step, "#f2f3f6");
    lines(metre, COLORS.grid);
    lines(metre * 5, COLORS.gridMajor);
    // axes
    ctx.beginPath();
    line(x0, 0, x1, 0);
    line(0, y0, 0, y1);
    ctx.strokeStyle = "#c9ced8";
    ctx.stroke();
  }

  function drawBounds() {
    const b = state.map.bounds;
    if (!Array.isArray(b) || b.length !== 4 || !b.every(Number.isFinite)) return;
    const p = worldToScreen(b[0], b[3]);
    const q = worldToScreen(b[2], b[1]);
    ctx.save();
    ctx.setLineDash([6, 4]);
    ctx.strokeStyle = COLORS.bounds;
    ctx.lineWidth = 1.5;
    ctx.strokeRect(p[0], p[1], q[0] - p[0], q[1] - p[1]);
    ctx.restore();
  }

  function zoneRectScreen(z) {
    const [x0, y0, x1, y1] = z.rect;
    const p = worldToScreen(Math.min(x0, x1), Math.max(y0, y1));
    const q = worldToScreen(Math.max(x0, x1), Math.min(y0, y1));
    return [p[0], p[1], q[0] - p[0], q[1] - p[1]];
  }

  function drawZones() {
    ctx.font = "12px system-ui, sans-serif";
    list("zones").forEach((z, i) => {
      if (!Array.isArray(z.rect) || z.rect.length !== 4) return;
      const [x, y, w, h] = zoneRectScreen(z);
      ctx.fillStyle = COLORS.zone;
      ctx.fillRect(x, y, w, h);
      const selected = state.selection && state.selection.kind === "zone" && state.selection.index === i;
      ctx.strokeStyle = selected ? COLORS.select : COLORS.zoneLine;
      ctx.lineWidth = selected ? 2 : 1;
      ctx.strokeRect(x, y, w, h);
      ctx.fillStyle = "#854d0e";
      ctx.fillText(z.name, x + 4, y + 14);
      if (selected) {
        ctx.fillStyle = COLORS.select;
        for (const [cx, cy] of [[x, y], [x + w, y], [x, y + h], [x + w, y + h]]) ctx.fillRect(cx - 3, cy - 3, 6, 6);
      }
    });
  }

  function drawEdges() {
    const ids = nodeIndexById();
    ctx.beginPath();
    for (const e of list("edges")) {
      const p = nodePosition(e[0], ids);
      const q = nodePosition(e[1], ids);
      if (p && q) line(p[0], p[1], q[0], q[1]);
    }
    ctx.strokeStyle = COLORS.edge;
    ctx.lineWidth = 1.2;
    ctx.stroke();
    const s = state.selection;
    if (s && s.kind === "edge") {
      const e = list("edges")[s.index];
      const p = e && nodePosition(e[0], ids);
      const q = e && nodePosition(e[1], ids);
      if (p && q) {
        ctx.beginPath();
        line(p[0], p[1], q[0], q[1]);
        ctx.strokeStyle = COLORS.select;
        ctx.lineWidth = 3;
        ctx.stroke();
      }
    }
  }

  function drawWalls() {
    const width = Math.max(2, Math.min(0.1 * state.view.scale, 8));
    ctx.lineCap = "round";
    ctx.beginPath();
    for (const w of list("walls")) line(w[0], w[1], w[2], w[3]);
    ctx.strokeStyle = COLORS.wall;
    ctx.lineWidth = width;
    ctx.stroke();
    const s = state.selection;
    if (s && s.kind === "wall" && list("walls")[s.index]) {
      const w = list("walls")[s.index];
      ctx.beginPath();
      line(w[0], w[1], w[2], w[3]);
      ctx.strokeStyle = COLORS.select;
      ctx.lineWidth = width;
      ctx.stroke();
      ctx.fillStyle = COLORS.select;
      for (const [x, y] of [[w[0], w[1]], [w[2], w[3]]]) {
        const [sx, sy] = worldToScreen(x, y);
        ctx.beginPath();
        ctx.arc(sx, sy, width / 2 + 3, 0, 2 * Math.PI);
        ctx.fill();
      }
    }
    ctx.lineCap = "butt";
  }

  function groupRoles() {
    const roles = new Map(); // id -> {start, goal, pedStart, pedGoal}
    const get = (id) => { if (!roles.has(id)) roles.set(id, {}); return roles.get(id); };
    for (const g of list("groups")) {
      for (const id of g.starts || []) get(id).start = true;
      for (const id of g.goals || []) get(id).goal = true;
    }
    for (const r of list("routes")) {
      if (r.length >= 2) { get(r[0]).start = true; get(r[r.length - 1]).goal = true; }
    }
    for (const g of list("pedestrian_groups")) {
      for (const id of g.starts || []) get(id).pedStart = true;
      for (const id of g.goals || []) get(id).pedGoal = true;
    }
    return roles;
  }

  function drawNodes() {
    const nodes = list("nodes");
    const roles = groupRoles();
    const r = Math.max(3, Math.min(6, 0.12 * state.view.scale));
    const labels = nodes.length <= 400 && state.view.scale >= 12;
    const current = state.tool === "group" ? currentGroups()[state.group.index] : null;
    ctx.font = "10px system-ui, sans-serif";
    nodes.forEach((n, i) => {
      const [sx, sy] = worldToScreen(n.position[0], n.position[1]);
      const role = roles.get(n.id) || {};
      ctx.beginPath();
      ctx.arc(sx, sy, r, 0, 2 * Math.PI);
      ctx.fillStyle = role.start && role.goal ? COLORS.start : role.start ? COLORS.start : role.goal ? COLORS.goal : COLORS.node;
      ctx.fill();
      if (role.start && role.goal) { // half and half
        ctx.beginPath();
        ctx.moveTo(sx, sy);
        ctx.arc(sx, sy, r, -Math.PI / 2, Math.PI / 2);
        ctx.closePath();
        ctx.fillStyle = COLORS.goal;
        ctx.fill();
      }
      ctx.beginPath();
      ctx.arc(sx, sy, r, 0, 2 * Math.PI);
      ctx.strokeStyle = COLORS.nodeLine;
      ctx.lineWidth = 1;
      ctx.stroke();
      if (role.pedStart || role.pedGoal) { // pedestrian groups: a dashed outer ring
        ctx.save();
        ctx.setLineDash([2, 2]);
        ctx.beginPath();
        ctx.arc(sx, sy, r + 3, 0, 2 * Math.PI);
        ctx.strokeStyle = role.pedStart ? "#0d9488" : "#a21caf";
        ctx.stroke();
        ctx.restore();
      }
      if (current) {
        const inStarts = (current.starts || []).includes(n.id);
        const inGoals = (current.goals || []).includes(n.id);
        if (inStarts || inGoals) {
          ctx.beginPath();
          ctx.arc(sx, sy, r + 4, 0, 2 * Math.PI);
          ctx.strokeStyle = inStarts && inGoals ? "#7c3aed" : inStarts ? COLORS.start : COLORS.goal;
          ctx.lineWidth = 2.5;
          ctx.stroke();
        }
      }
      const selected = state.selection && state.selection.kind === "node" && state.selection.index === i;
      if (selected || state.edgeFrom === n.id) {
        ctx.beginPath();
        ctx.arc(sx, sy, r + 3, 0, 2 * Math.PI);
        ctx.strokeStyle = COLORS.select;
        ctx.lineWidth = 2;
        ctx.stroke();
      }
      if (labels) {
        ctx.fillStyle = "#334155";
        ctx.fillText(String(n.id), sx + r + 2, sy - r - 1);
      }
    });
  }

  function drawRoutes() {
    const routes = state.routes && Array.isArray(state.routes.routes) ? state.routes.routes : [];
    ctx.save();
    ctx.lineJoin = "round";
    for (const route of routes) {
      const pts = route.points || [];
      if (pts.length < 2) continue;
      ctx.beginPath();
      pts.forEach((p, k) => {
        const [sx, sy] = worldToScreen(p[0], p[1]);
        if (k === 0) ctx.moveTo(sx, sy); else ctx.lineTo(sx, sy);
      });
      if (route.tie) {
        ctx.setLineDash([7, 5]);
        ctx.strokeStyle = COLORS.tie;
        ctx.lineWidth = 2.5;
      } else {
        ctx.setLineDash([]);
        ctx.strokeStyle = COLORS.route;
        ctx.lineWidth = 2;
      }
      ctx.stroke();
    }
    ctx.restore();
    if (state.routes && state.routes.error) {
      ctx.font = "11px system-ui, sans-serif";
      ctx.fillStyle = COLORS.error;
      ctx.fillText(state.routes.error, 8, 16);
    } else if (state.routes) {
      ctx.font = "11px system-ui, sans-serif";
      ctx.fillStyle = "#334155";
      const ties = routes.filter((r) => r.tie).length;
      ctx.fillText(`${state.routes.pairs} pairs, ${routes.length} routes shown${state.routes.truncated ? " (truncated)" : ""}${ties ? `, ${ties} ties (dashed)` : ""}`, 8, 16);
    }
  }

  function strokeElement(kind, index, color, width) {
    const m = state.map;
    ctx.save();
    ctx.strokeStyle = color;
    ctx.lineWidth = width;
    ctx.lineCap = "round";
    if (kind === "wall" || kind === "edge") {
      const pts = elementPoints(kind, index);
      if (pts.length === 2) {
        ctx.beginPath();
        line(pts[0][0], pts[0][1], pts[1][0], pts[1][1]);
        ctx.stroke();
      }
    } else if (kind === "node" || kind === "group" || kind === "pedestrian_group") {
      for (const p of elementPoints(kind, index)) {
        const [sx, sy] = worldToScreen(p[0], p[1]);
        ctx.beginPath();
        ctx.arc(sx, sy, 10, 0, 2 * Math.PI);
        ctx.stroke();
      }
    } else if (kind === "route") {
      const pts = elementPoints(kind, index);
      ctx.beginPath();
      pts.forEach((p, k) => {
        const [sx, sy] = worldToScreen(p[0], p[1]);
        if (k === 0) ctx.moveTo(sx, sy); else ctx.lineTo(sx, sy);
      });
      ctx.stroke();
    } else if (kind === "zone") {
      const z = list("zones")[index];
      if (z && Array.isArray(z.rect)) ctx.strokeRect(...zoneRectScreen(z));
    } else if (kind === "bounds" && Array.isArray(m.bounds) && m.bounds.length === 4) {
      ctx.strokeRect(...zoneRectScreen({ rect: m.bounds }));
    }
    ctx.restore();
  }

  function drawProblems() {
    // warnings first so that errors are drawn on top
    const order = state.problems.map((p, i) => i).sort((a, b) =>
      (state.problems[a].severity === "error") - (state.problems[b].severity === "error"));
    for (const i of order) {
      const p = state.problems[i];
      const color = p.severity === "error" ? COLORS.error : COLORS.warning;
      const active = i === state.activeProblem;
      const el = p.element || {};
      if (el.kind && el.index !== null && el.index !== undefined) strokeElement(el.kind, el.index, color, active ? 5 : 3);
      else if (el.kind === "bounds") strokeElement("bounds", null, color, active ? 5 : 3);
      if (Array.isArray(p.point) && p.point.length === 2) {
        const [sx, sy] = worldToScreen(p.point[0], p.point[1]);
        ctx.beginPath();
        ctx.arc(sx, sy, active ? 16 : 12, 0, 2 * Math.PI);
        ctx.strokeStyle = color;
        ctx.lineWidth = active ? 3 : 2;
        ctx.stroke();
      }
    }
  }

  function drawHover() {
    const h = state.hover;
    if (!h || state.drag) return;
    const color = state.tool === "delete" ? "rgba(209, 31, 31, 0.6)" : "rgba(37, 99, 235, 0.45)";
    strokeElement(h.kind, h.index, color, h.kind === "node" ? 2 : 4);
  }

  function drawLabel(text, px, py) {
    ctx.font = "12px system-ui, sans-serif";
    const w = ctx.measureText(text).width;
    ctx.fillStyle = "rgba(255, 255, 255, 0.85)";
    ctx.fillRect(px + 12, py + 8, w + 8, 17);
    ctx.fillStyle = "#111827";
    ctx.fillText(text, px + 16, py + 21);
  }

  function drawToolPreview() {
    const c = state.cursor;
    if (state.tool === "wall" && c) {
      const p = snapPoint(c.px, c.py);
      const [sx, sy] = worldToScreen(p.x, p.y);
      if (state.chain) {
        ctx.beginPath();
        line(state.chain.x, state.chain.y, p.x, p.y);
        ctx.strokeStyle = "rgba(38, 43, 54, 0.55)";
        ctx.lineWidth = Math.max(3, Math.min(0.1 * state.view.scale, 8));
        ctx.stroke();
        drawLabel(`${fmt(Math.hypot(p.x - state.chain.x, p.y - state.chain.y))} m`, sx, sy);
      }
      ctx.beginPath();
      ctx.arc(sx, sy, p.snapped ? 6 : 3, 0, 2 * Math.PI);
      ctx.strokeStyle = COLORS.select;
      ctx.lineWidth = 1.5;
      ctx.stroke();
    }
    if ((state.tool === "node" || state.tool === "zone") && c && !state.drag) {
      const p = snapPoint(c.px, c.py, state.tool === "zone");
      const [sx, sy] = worldToScreen(p.x, p.y);
      ctx.beginPath();
      ctx.arc(sx, sy, 4, 0, 2 * Math.PI);
      ctx.strokeStyle = COLORS.select;
      ctx.lineWidth = 1.5;
      ctx.stroke();
      if (state.tool === "node") drawLabel(`node ${nextNodeId()} (${fmt(p.x)}, ${fmt(p.y)})`, sx, sy);
    }
    if (state.tool === "edge" && state.edgeFrom !== null && c) {
      const p = nodePosition(state.edgeFrom);
      if (p) {
        ctx.save();
        ctx.setLineDash([4, 4]);
        ctx.beginPath();
        line(p[0], p[1], c.x, c.y);
        ctx.strokeStyle = COLORS.select;
        ctx.lineWidth = 1.5;
        ctx.stroke();
        ctx.restore();
      }
    }
    const d = state.drag;
    if (d && d.type === "newZone") {
      const rect = [d.start.x, d.start.y, d.end.x, d.end.y];
      const [x, y, w, h] = zoneRectScreen({ rect });
      ctx.fillStyle = COLORS.zone;
      ctx.fillRect(x, y, w, h);
      ctx.strokeStyle = COLORS.select;
      ctx.lineWidth = 1.5;
      ctx.strokeRect(x, y, w, h);
      drawLabel(`${fmt(Math.abs(d.end.x - d.start.x))} x ${fmt(Math.abs(d.end.y - d.start.y))} m`, x + w, y + h);
    }
    if (d && d.type === "groupBox") {
      const [x, y, w, h] = zoneRectScreen({ rect: [d.start.x, d.start.y, d.end.x, d.end.y] });
      ctx.save();
      ctx.setLineDash([5, 4]);
      ctx.strokeStyle = state.group.phase === "starts" ? COLORS.start : COLORS.goal;
      ctx.lineWidth = 1.5;
      ctx.strokeRect(x, y, w, h);
      ctx.restore();
    }
    if (state.tool === "group" && c) {
      drawLabel(`group ${state.group.index} (${state.group.kind === "groups" ? "robots" : "pedestrians"}): ${state.group.phase}`, c.px, c.py);
    }
  }

  function drawPlayback() {
    const ep = state.playback.episode;
    const t = playbackFrame();
    const frame = ep.frames[t] || [];
    const present = ep.present || [];
    const radius = ep.radius || [];
    // goals: crosses
    (ep.goals || []).forEach((g, i) => {
      if (present[i] === false) return;
      const [sx, sy] = worldToScreen(g[0], g[1]);
      ctx.beginPath();
      ctx.moveTo(sx - 6, sy - 6); ctx.lineTo(sx + 6, sy + 6);
      ctx.moveTo(sx - 6, sy + 6); ctx.lineTo(sx + 6, sy - 6);
      ctx.strokeStyle = ROBOT_COLORS[i % ROBOT_COLORS.length];
      ctx.lineWidth = 2.5;
      ctx.stroke();
    });
    // pedestrians
    const humans = (ep.humans || [])[t] || [];
    const hr = Math.max(2, (ep.human_radius || 0.2) * state.view.scale);
    ctx.fillStyle = "rgba(107, 114, 128, 0.75)";
    for (const h of humans) {
      const [sx, sy] = worldToScreen(h[0], h[1]);
      ctx.beginPath();
      ctx.arc(sx, sy, hr, 0, 2 * Math.PI);
      ctx.fill();
    }
    // robots with a heading tick
    frame.forEach((r, i) => {
      if (present[i] === false) return;
      const [sx, sy] = worldToScreen(r[0], r[1]);
      const rad = Math.max(3, (radius[i] || 0.25) * state.view.scale);
      const color = ROBOT_COLORS[i % ROBOT_COLORS.length];
      ctx.beginPath();
      ctx.arc(sx, sy, rad, 0, 2 * Math.PI);
      ctx.fillStyle = color + "55";
      ctx.fill();
      ctx.strokeStyle = color;
      ctx.lineWidth = 2;
      ctx.stroke();
      const heading = r[2] || 0;
      ctx.beginPath();
      ctx.moveTo(sx, sy);
      ctx.lineTo(sx + Math.cos(heading) * rad, sy - Math.sin(heading) * rad);
      ctx.stroke();
    });
    const length = Math.min(ep.length || ep.frames.length, ep.frames.length);
    const arrived = (ep.arrived || []).filter(Boolean).length;
    ctx.font = "12px system-ui, sans-serif";
    ctx.fillStyle = "#111827";
    ctx.fillText(`episode 0: t = ${fmt(t * (ep.dt || 0), 1)} s of ${fmt(length * (ep.dt || 0), 1)} s, ${arrived} of ${present.filter((p) => p !== false).length} arrived`, 8, state.size.h - 22);
  }

  // ---------------------------------------------------------------- start

  window.sgjaxEditor = {
    getMap: () => (state.map ? clone(state.map) : null),
    setMap: (map) => setMap(map),
    worldToScreen: (x, y) => worldToScreen(x, y),
    screenToWorld: (px, py) => screenToWorld(px, py),
    problems: () => clone(state.problems),
    routes: () => (state.routes ? clone(state.routes) : null), // the last /api/routes answer
    get ready() { return state.ready; },
    busy: () => state.checkTimer !== null || state.pending.check > 0 || state.pending.save > 0 ||
      state.pending.play > 0 || state.pending.routes > 0 || state.pending.generate > 0,
    fit: () => fitView(),
    setTool: (tool) => setTool(tool),
  };

  if (window.ResizeObserver) new ResizeObserver(resize).observe(canvas);
  window.addEventListener("resize", resize);
  resize();
  setTool("select");
  loadSession();
})();
