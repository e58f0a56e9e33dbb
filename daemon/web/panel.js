// fogbench's live panel (docs/web.md): one WebSocket to fogbenchd's /ws carrying the command
// protocol (docs/protocol.md): it subscribes to the `sample` and `event` stream, asks `status`
// every 2 s, loads the last hour of the active run with `run.samples`, and plots with uPlot.
// Control requests (run.start, run.abort) carry the token typed in; the daemon decides. When the
// connection drops (the daemon restarts) it reconnects by itself, waiting 0.5 s to 5 s.
// For the operator (docs/web.md, "The operator's screen"): a large verdict per slot and serial
// (#board), the wall-clock time (the header's clock, the run's start and expected end, the
// events' times), and plots that follow the window's width and the printed page's.
"use strict";
(function () {
  const HOUR_S = 3600;
  const $ = (id) => document.getElementById(id);
  let ws = null;
  let nextId = 1;
  const pending = new Map();
  let connects = 0;
  let retryMs = 500;
  let statusTimer = null;

  // The plotted run: rows by run time t_s, each {t, sp, air, u: [{t1, t2, raw, comp}]}.
  let runId = null;
  let serials = [];
  let rows = [];
  let plots = null;
  let drawQueued = false;
  let samplesSeen = 0;

  function fmtS(s) {
    if (s === null || s === undefined) return "";
    s = Math.round(s);
    const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), r = s % 60;
    return (h ? h + " h " : "") + (h || m ? m + " min " : "") + r + " s";
  }
  function fmtC(v) { return v === null || v === undefined ? "-" : v.toFixed(2) + " degC"; }
  // Wall-clock times in the browser's local time zone, 24 h: "2026-11-28 16:50:03", "16:50".
  const pad2 = (n) => (n < 10 ? "0" : "") + n;
  function fmtDate(d) { return d.getFullYear() + "-" + pad2(d.getMonth() + 1) + "-" + pad2(d.getDate()); }
  function fmtTime(d, seconds) { return pad2(d.getHours()) + ":" + pad2(d.getMinutes()) + (seconds ? ":" + pad2(d.getSeconds()) : ""); }
  function fmtWall(d) {
    if (!d || isNaN(d.getTime())) return "";
    const today = fmtDate(new Date()) === fmtDate(d);
    return (today ? "" : fmtDate(d) + " ") + fmtTime(d, false);
  }
  function parseIso(t) { if (!t) return null; const d = new Date(t); return isNaN(d.getTime()) ? null : d; }
  function tickClock() {
    const now = new Date();
    const c = $("clock");
    c.textContent = fmtDate(now) + " " + fmtTime(now, true);
    c.dataset.epochMs = String(now.getTime());
  }

  function call(req) {
    return new Promise((resolve, reject) => {
      if (!ws || ws.readyState !== WebSocket.OPEN) return reject(new Error("not connected"));
      const id = nextId++;
      pending.set(id, resolve);
      ws.send(JSON.stringify(Object.assign({}, req, { id: id })));
    });
  }

  // --- plots
  function palette(i) { return ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#7f7f7f"][i % 8]; }
  function makePlot(el, ylabel, series) {
    el.innerHTML = "";
    const width = plotWidth(el);
    return new uPlot({
      width: width, height: 220,
      scales: { x: { time: false } },
      series: [{ label: "run time, s" }].concat(series),
      axes: [{ label: "run time, s" }, { label: ylabel }],
      legend: { live: true },
    }, [[]].concat(series.map(() => [])), el);
  }
  // The plot's width: its box's (the window's or, printing, the page's), at least 280 px.
  function plotWidth(el) { return Math.max(280, (el.clientWidth || 900) - 10); }
  function fitPlots() {
    if (!plots) return;
    [["chamber", "plot-chamber"], ["coil", "plot-coil"], ["drift", "plot-drift"]].forEach(([k, id]) => {
      const w = plotWidth($(id));
      if (plots[k].width !== w) plots[k].setSize({ width: w, height: 220 });
    });
  }
  let fitTimer = null;
  window.addEventListener("resize", () => { clearTimeout(fitTimer); fitTimer = setTimeout(fitPlots, 150); });
  // Printing: the plots take the page's width before it is laid out, and the window's after.
  window.addEventListener("beforeprint", fitPlots);
  window.addEventListener("afterprint", fitPlots);
  if (window.matchMedia) {
    const mq = window.matchMedia("print");
    if (mq.addEventListener) mq.addEventListener("change", fitPlots);
  }
  function buildPlots() {
    const coil = [], drift = [];
    serials.forEach((s, i) => {
      coil.push({ label: s + " T1", stroke: palette(i) }, { label: s + " T2", stroke: palette(i), dash: [6, 4] });
      drift.push({ label: s + " raw", stroke: palette(i) }, { label: s + " compensated", stroke: palette(i + 4) });
    });
    plots = {
      chamber: makePlot($("plot-chamber"), "degC", [
        { label: "setpoint", stroke: "#888", dash: [6, 4] }, { label: "air", stroke: "#d62728" }]),
      coil: makePlot($("plot-coil"), "degC", coil),
      drift: makePlot($("plot-drift"), "deg/h", drift),
    };
  }
  function queueDraw() {
    if (drawQueued) return;
    drawQueued = true;
    setTimeout(draw, 250);
  }
  function draw() {
    drawQueued = false;
    if (!plots) return;
    if (rows.length) {
      const last = rows[rows.length - 1].t;
      let k = 0;
      while (k < rows.length && rows[k].t < last - HOUR_S) k++;
      if (k) rows = rows.slice(k);
    }
    const t = rows.map((r) => r.t);
    const v = (f) => rows.map((r) => (f(r) === undefined ? null : f(r)));
    plots.chamber.setData([t, v((r) => r.sp), v((r) => r.air)]);
    const coil = [t], drift = [t];
    serials.forEach((s, i) => {
      coil.push(v((r) => r.u[i] && r.u[i].t1), v((r) => r.u[i] && r.u[i].t2));
      drift.push(v((r) => r.u[i] && r.u[i].raw), v((r) => r.u[i] && r.u[i].comp));
    });
    plots.coil.setData(coil);
    plots.drift.setData(drift);
    $("plot-drift").dataset.points = String(t.length);  // what the plots hold, for tests and people
  }
  // One sample (pushed, or a row of run.samples) into the rows, which stay in time order.
  function addSample(unit, s) {
    let i = rows.length - 1;
    while (i >= 0 && rows[i].t > s.t_s) i--;
    let row;
    if (i >= 0 && rows[i].t === s.t_s) row = rows[i];
    else {
      row = { t: s.t_s, sp: null, air: null, u: [] };
      rows.splice(i + 1, 0, row);
    }
    if (s.setpoint_c !== undefined) row.sp = s.setpoint_c;
    if (s.chamber_c !== undefined) row.air = s.chamber_c;
    row.u[unit] = { t1: s.t1_c, t2: s.t2_c, raw: s.gyro_dph,
                    comp: s.compensated_dph === undefined ? null : s.compensated_dph };
  }

  function startRun(id, units) {
    runId = id;
    serials = units.slice();
    rows = [];
    buildPlots();
  }

  // The last hour of the active run, unit by unit: its count first, then the page.
  async function loadHistory(id) {
    for (let u = 0; u < serials.length; u++) {
      try {
        const head = await call({ cmd: "run.samples", run_id: id, unit: u, limit: 1 });
        if (!head.result || runId !== id) return;
        const total = head.result.total;
        const offset = Math.max(0, total - HOUR_S);
        const page = await call({ cmd: "run.samples", run_id: id, unit: u, offset: offset, limit: Math.min(HOUR_S, 10000) });
        if (!page.result || runId !== id) return;
        page.result.samples.forEach((s) => addSample(u, s));
      } catch (e) { return; }
    }
    queueDraw();
  }

  // --- the run box
  function showStatus(st) {
    $("daemon").textContent = "fogbenchd " + st.version + (st.simulated ? " (mock bench, time scale " + st.time_scale + ")" : "");
    const ch = st.chamber || {};
    $("chamber-now").textContent = "air " + fmtC(ch.chamber_c) + ", setpoint " + fmtC(st.setpoint_c);
    $("chamber-link").textContent = ch.link + (ch.alarm ? ", ALARM" : "");
    const r = st.run;
    $("run-id").textContent = r ? String(r.id) : "none";
    $("run-state").textContent = r ? r.state : (st.last_run ? "idle (last: run " + st.last_run.run_id + " " + st.last_run.state + ")" : "idle");
    $("run-profile").textContent = r ? r.profile + " (" + r.purpose + ")" : "";
    $("run-step").textContent = r ? String(r.step) + (r.phase ? " (" + r.phase + ")" : "") : "";
    $("run-elapsed").textContent = r ? fmtS(r.elapsed_s) : "";
    $("run-remaining").textContent = r ? fmtS(r.remaining_s) : "";
    // Wall-clock: the run's start (run.list's started_at, else the elapsed run seconds back from
    // now) and its expected end (the remaining profile seconds at the daemon's time scale).
    const scale = st.time_scale > 0 ? st.time_scale : 1;
    const listed = r ? recentRuns.find((x) => x.id === r.id) : null;
    const started = r ? (parseIso(listed && listed.started_at) ||
                         (r.elapsed_s !== null && r.elapsed_s !== undefined ? new Date(Date.now() - 1000 * r.elapsed_s / scale) : null)) : null;
    const ends = r && r.remaining_s !== null && r.remaining_s !== undefined ? new Date(Date.now() + 1000 * r.remaining_s / scale) : null;
    $("run-started").textContent = started ? fmtWall(started) : "";
    $("run-ends").textContent = ends ? "about " + fmtWall(ends) : "";
    $("run-ends").dataset.epochMs = ends ? String(ends.getTime()) : "";
    const was = activeRun ? activeRun.id + " " + activeRun.state : "";
    activeRun = r || null;
    if (was !== (r ? r.id + " " + r.state : "")) showBoard();
    // One serial entry per bench slot (docs/web.md): typed, or a barcode scanner's input and its
    // Enter, which moves on to the next slot (from the last, to Start). Prefilled with the slot's
    // configured default serial; an empty slot takes no part in the run.
    const unitsEl = $("units");
    if (!unitsEl.childElementCount && st.units) {
      st.units.forEach((u, i) => {
        const slot = u.slot || String.fromCharCode(65 + i);  // a daemon before slots: A, B, ...
        const l = document.createElement("label");
        const c = document.createElement("input");
        c.type = "text"; c.size = 12; c.className = "slot-serial"; c.dataset.slot = slot;
        c.placeholder = "scan serial"; c.value = u.serial || ""; c.autocomplete = "off";
        c.addEventListener("keydown", (e) => {
          if (e.key !== "Enter") return;
          e.preventDefault();
          const all = Array.from(document.querySelectorAll("input.slot-serial"));
          const next = all[all.indexOf(c) + 1];
          (next || $("start")).focus();
          if (next) next.select();
        });
        l.appendChild(document.createTextNode("slot " + slot + " "));
        l.appendChild(c);
        unitsEl.appendChild(l);
      });
    }
    if (r && r.id !== runId) {
      startRun(r.id, r.units);
      loadHistory(r.id);
      refreshVerdicts();  // the new run heads the table
    }
  }
  async function refreshStatus() {
    try {
      const s = await call({ cmd: "status" });
      if (s.result) showStatus(s.result);
    } catch (e) { /* reconnecting */ }
  }

  async function refreshProfiles() {
    const r = await call({ cmd: "profile.list" });
    if (!r.result) return;
    const sel = $("profile");
    const keep = sel.value;
    sel.innerHTML = "";
    r.result.profiles.filter((p) => p.valid).forEach((p) => {
      const o = document.createElement("option");
      o.value = p.name;
      o.textContent = p.name + " (" + fmtS(p.nominal_duration_s) + ")";
      sel.appendChild(o);
    });
    if (keep) sel.value = keep;
  }

  // The last five runs and their verdicts. One refresh at a time: a refresh asked for while one
  // is under way (a run's end and the next run's start, a reconnect) runs once more after it,
  // and the table is replaced whole when a refresh has every row, so no run is listed twice
  // and the rows stay newest first.
  let verdictsRunning = null;
  let verdictsAgain = false;
  let recentRuns = [];  // run.list's runs, newest first, each with its run.get `verdicts`, `models`
  function refreshVerdicts() {
    if (verdictsRunning) { verdictsAgain = true; return verdictsRunning; }
    verdictsRunning = (async () => {
      try {
        do { verdictsAgain = false; await loadVerdicts(); } while (verdictsAgain);
      } finally { verdictsRunning = null; }
    })();
    return verdictsRunning;
  }
  async function loadVerdicts() {
    let list;
    try { list = await call({ cmd: "run.list", limit: 5 }); } catch (e) { return; }
    if (!list.result) return;
    const seen = new Set();
    const runs = list.result.runs.filter((r) => !seen.has(r.id) && seen.add(r.id)).sort((a, b) => b.id - a.id);
    for (const run of runs) {
      if (run.state !== "completed") continue;
      try {
        const g = await call({ cmd: "run.get", run_id: run.id });
        if (g.result) { run.verdicts = g.result.verdicts || []; run.models = g.result.models || []; }
      } catch (e) { return; }  // disconnected: the reconnect refreshes
    }
    const body = document.createElement("tbody");
    for (const run of runs) {
      const tr = document.createElement("tr");
      tr.dataset.runId = String(run.id);
      const started = parseIso(run.started_at);
      for (const text of [run.id, started ? fmtWall(started) : "", run.profile, run.purpose,
                          run.state + (run.reason ? ": " + run.reason : "")]) {
        const td = document.createElement("td");
        td.textContent = String(text);
        tr.appendChild(td);
      }
      const v = document.createElement("td");
      const parts = [];
      // Each unit's one verdict (issue 24): the station decided it once; the panel only shows it.
      (run.verdicts || []).forEach((x) => {
        if (!x) return;
        const span = document.createElement("span");
        if (x.verdict) {
          span.className = x.verdict;
          span.textContent = x.serial + " " + x.verdict.toUpperCase() + " (" +
            (x.plan ? "plan " + (x.plan.name || x.plan.id) : "analysis settings") + ")";
        } else {
          span.textContent = x.serial + ": " + (x.pending || "no verdict");
        }
        parts.push(span.outerHTML);
        // A three-axis unit: each axis' verdict beside the unit's (the worst of them).
        const axes = axisVerdicts(x.axes);
        if (axes.length) parts.push(axesElement(axes, "axes-line", x.serial).outerHTML);
      });
      (run.models || []).forEach((m) => parts.push(m.serial + " model v" + m.version));
      v.innerHTML = parts.join(", ");
      tr.appendChild(v);
      body.appendChild(tr);
    }
    const table = $("verdicts");
    table.replaceChild(body, table.querySelector("tbody"));
    recentRuns = runs;
    showBoard();
  }

  // --- a three-axis unit's axes (docs/web.md "Three-axis units"): [{axis, verdict}] from a
  // verdict's `axes` (run.get) or a plan unit's `axis_evidence` (plan.status, while it runs).
  function axisVerdicts(axes) {
    if (Array.isArray(axes))
      return axes.filter((a) => a && a.axis && a.verdict).map((a) => ({ axis: String(a.axis), verdict: String(a.verdict) }));
    if (axes && typeof axes === "object")
      return ["x", "y", "z"].filter((k) => axes[k] && axes[k].verdict).map((k) => ({ axis: k, verdict: String(axes[k].verdict) }));
    return [];
  }
  function axesElement(axes, className, serial) {
    const div = document.createElement("span");
    div.className = className;
    div.dataset.serial = serial;
    axes.forEach((a) => {
      const span = document.createElement("span");
      span.className = "axis " + a.verdict + " v-" + a.verdict;
      span.dataset.axis = a.axis;
      span.dataset.verdict = a.verdict;
      span.textContent = a.axis + " " + a.verdict.toUpperCase();
      div.appendChild(span);
    });
    return div;
  }
  // The stored verdict of `serial` in the runs shown (newest first), if one was decided there.
  function storedVerdict(serial, planId) {
    for (const run of recentRuns)
      for (const v of run.verdicts || [])
        if (v && v.serial === serial && v.verdict && (planId === undefined || (v.plan && v.plan.id === planId))) return v;
    return null;
  }

  // --- the board: each unit of what ran last, its slot, serial and verdict, large (docs/web.md).
  let activeRun = null;  // status.run
  let shownPlan = null;  // plan.js's plan.status (the running plan, else the last one)
  const WORDS = { pass: "PASS", marginal: "MARGINAL", fail: "FAIL", incomplete: "INCOMPLETE", testing: "IN TEST",
                  pending: "PENDING", none: "NO VERDICT", aborted: "ABORTED", failed: "RUN FAILED" };
  function boardUnits() {
    const p = shownPlan, pr = p && p.progress && typeof p.progress === "object" ? p.progress : null;
    const newest = recentRuns[0] || null;
    const planTiles = () => (pr.units || []).map((u) => {
      const inRun = activeRun && (activeRun.units || []).includes(u.serial);
      const verdict = u.verdict || (p.state === "running" ? (inRun ? "testing" : "pending") : "pending");
      // The axes as decided (the stored verdict of this plan), else as judged so far.
      const stored = u.verdict ? storedVerdict(u.serial, p.plan_id) : null;
      return { slot: (p.slots || {})[u.serial] || "", serial: u.serial, verdict: verdict,
               axes: axisVerdicts(stored && stored.axes ? stored.axes : u.axis_evidence),
               note: "plan " + p.plan_id + " " + p.name + (u.verdict ? "" : (u.marginal ? ", marginal so far" : "")) +
                     (inRun ? ", run " + activeRun.id : "") };
    });
    if (p && pr && p.state === "running") return planTiles();
    if (activeRun) {
      return (activeRun.units || []).map((serial, i) => ({
        slot: (activeRun.slots || [])[i] || "", serial: serial, verdict: "testing",
        note: "run " + activeRun.id + " " + activeRun.profile + " (" + activeRun.purpose + ")" }));
    }
    if (p && pr && newest && (pr.runs || []).some((r) => r.run_id === newest.id)) return planTiles();
    if (!newest) return [];
    return (newest.units || []).map((serial, i) => {
      const x = (newest.verdicts || []).find((v) => v && v.serial === serial);
      let verdict;
      if (newest.state !== "completed") verdict = newest.state === "aborted" || newest.state === "interrupted" ? "aborted" : "failed";
      else if (x && x.verdict) verdict = x.verdict;
      else if (x && x.pending) verdict = "pending";
      else verdict = "none";
      return { slot: (newest.slots || [])[i] || "", serial: serial, verdict: verdict,
               axes: newest.state === "completed" && x ? axisVerdicts(x.axes) : [],
               note: "run " + newest.id + " " + newest.profile + " (" + newest.purpose + ")" +
                     (x && x.plan ? ", plan " + (x.plan.name || x.plan.id) : "") };
    });
  }
  function showBoard() {
    const board = $("board-units");
    const units = boardUnits();
    board.innerHTML = "";
    units.forEach((u) => {
      const tile = document.createElement("div");
      tile.className = "tile v-" + u.verdict;
      tile.dataset.slot = u.slot;
      tile.dataset.serial = u.serial;
      tile.dataset.verdict = u.verdict;
      const head = document.createElement("div");
      head.className = "who";
      head.textContent = (u.slot ? "slot " + u.slot + "  " : "") + u.serial;
      const big = document.createElement("div");
      big.className = "big";
      big.textContent = WORDS[u.verdict] || u.verdict.toUpperCase();
      const note = document.createElement("div");
      note.className = "what";
      note.textContent = u.note;
      tile.appendChild(head); tile.appendChild(big);
      if (u.axes && u.axes.length) tile.appendChild(axesElement(u.axes, "axes", u.serial));
      tile.appendChild(note);
      board.appendChild(tile);
    });
    $("board-empty").style.display = units.length ? "none" : "";
    board.dataset.count = String(units.length);
  }
  function planShown(p) {
    const before = shownPlan ? shownPlan.plan_id + " " + shownPlan.state : "";
    shownPlan = p;
    showBoard();
    // A plan that has just ended decided its units' verdicts: the runs' table shows them.
    if (before && p && before !== p.plan_id + " " + p.state) refreshVerdicts();
  }

  // --- events
  function addEvent(e) {
    const li = document.createElement("li");
    li.className = e.kind;
    const t = e.t_s === null || e.t_s === undefined ? "" : "t=" + e.t_s + " s ";
    const at = document.createElement("time");
    const now = new Date();
    at.dateTime = now.toISOString();
    at.textContent = fmtTime(now, true) + " ";
    li.textContent = t + "run " + e.run_id + " " + e.kind + ": " + JSON.stringify(e.detail);
    li.insertBefore(at, li.firstChild);
    const ul = $("events");
    ul.insertBefore(li, ul.firstChild);
    while (ul.childElementCount > 200) ul.removeChild(ul.lastChild);
    ul.dataset.count = String(Number(ul.dataset.count) + 1);
    if (e.kind === "state" && e.detail && ["completed", "aborted", "failed"].includes(e.detail.to)) {
      refreshVerdicts();
      refreshStatus();
      if (window.fogPanel.refreshPlan) window.fogPanel.refreshPlan();  // plan.js: the plan's next step or its end
    }
  }

  // --- control
  function token() { return $("token").value; }
  function showResult(what, r) {
    const el = $("control-result");
    if (r.error) {
      el.className = "error";
      el.dataset.code = r.error.code;
      el.textContent = what + " refused (" + r.error.code + "): " + r.error.message;
    } else {
      el.className = "";
      el.dataset.code = "ok";
      el.textContent = what + ": " + JSON.stringify(r.result);
    }
    return r;
  }
  async function start() {
    // {slot: serial} of the slots with a serial; the daemon checks each (docs/protocol.md "Bench slots").
    const slots = {};
    document.querySelectorAll("input.slot-serial").forEach((c) => {
      const serial = c.value.trim();
      if (serial) slots[c.dataset.slot] = serial;
    });
    const req = { cmd: "run.start", profile: $("profile").value, slots: slots, purpose: $("purpose").value };
    if (token()) req.token = token();
    return showResult("start", await call(req));
  }
  async function abort() {
    const req = { cmd: "run.abort", reason: "from the web panel" };
    if (token()) req.token = token();
    return showResult("abort", await call(req));
  }
  $("start").addEventListener("click", () => start().catch((e) => showResult("start", { error: { code: "disconnected", message: e.message } })));
  $("abort").addEventListener("click", () => abort().catch((e) => showResult("abort", { error: { code: "disconnected", message: e.message } })));

  // --- the connection
  function setConn(up, text) {
    const c = $("conn");
    c.className = up ? "up" : "down";
    c.textContent = text;
  }
  function onMessage(ev) {
    let m;
    try { m = JSON.parse(ev.data); } catch (e) { return; }
    if (m.type === "reply") {
      const done = pending.get(m.id);
      if (done) { pending.delete(m.id); done(m); }
    } else if (m.type === "sample") {
      if (m.run_id !== runId) {
        // A run the status has not shown yet: its units come with the status.
        refreshStatus();
        return;
      }
      addSample(m.unit, m);
      samplesSeen++;
      const el = $("samples");
      el.dataset.count = String(samplesSeen);
      el.textContent = String(samplesSeen);
      queueDraw();
    } else if (m.type === "event") {
      addEvent(m);
    } else if (m.type === "hello") {
      $("daemon").textContent = "fogbenchd " + m.version;
    }
  }
  function connect() {
    const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws";
    setConn(false, connects ? "reconnecting" : "connecting");
    ws = new WebSocket(url);
    ws.onmessage = onMessage;
    ws.onopen = async () => {
      retryMs = 500;
      connects++;
      $("conn").dataset.connects = String(connects);
      setConn(true, "connected");
      try {
        await call({ cmd: "subscribe" });
        await refreshStatus();
        await refreshProfiles();
        await refreshVerdicts();
        if (window.fogPanel.refreshPlan) await window.fogPanel.refreshPlan();
      } catch (e) { /* dropped meanwhile: onclose reconnects */ }
    };
    ws.onclose = () => {
      pending.forEach((done) => done({ error: { code: "disconnected", message: "the connection to fogbenchd closed" } }));
      pending.clear();
      setConn(false, "disconnected; retrying");
      runId = null;  // the run is taken up again from the status after the reconnect
      setTimeout(connect, retryMs);
      retryMs = Math.min(retryMs * 2, 5000);
    };
  }
  statusTimer = setInterval(refreshStatus, 2000);
  tickClock();
  setInterval(tickClock, 1000);
  window.fogPanel = { call: call, start: start, abort: abort, refreshStatus: refreshStatus,
                      refreshVerdicts: refreshVerdicts, planShown: planShown, fitPlots: fitPlots };
  connect();
})();
