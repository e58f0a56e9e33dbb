// The live panel's plans (docs/web.md, "Plans"): the current plan (plan.status: the running one,
// else the last one) with its step, its units (dropped ones marked) and each unit's measurements
// per step against the plan's limits, and the queue (queue.list). Over panel.js's WebSocket
// (fogPanel.call), refreshed every 2 s and when a run ends. The plan goes to panel.js's board
// (fogPanel.planShown: its units' verdicts, large), and the queue's first plan to "Next".
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const el = (tag, text, cls) => {
    const e = document.createElement(tag);
    if (text !== undefined && text !== null) e.textContent = String(text);
    if (cls) e.className = cls;
    return e;
  };
  let busy = false;

  function fmtValue(m) {
    // A three-axis unit's measurement names its axis: "comp_raw (y) 0.821".
    const name = m.measurement + (m.axis ? " (" + m.axis + ")" : "");
    if (m.value === null || m.value === undefined) return name + " not measured";
    const v = Math.abs(m.value) >= 100 || m.value === 0 ? Number(m.value).toPrecision(4) : Number(m.value).toPrecision(3);
    return name + " " + v + (m.unit ? " " + m.unit : "");
  }

  function showPlan(p) {
    const box = $("plan");
    const pr = p && p.progress && typeof p.progress === "object" ? p.progress : null;
    if (!p) {
      box.dataset.planId = "";
      box.dataset.state = "";
      $("plan-title").textContent = "no plan has run";
      $("plan-trace").textContent = "";
      $("plan-steps").innerHTML = "";
      $("plan-units").querySelector("thead").innerHTML = "";
      $("plan-units").querySelector("tbody").innerHTML = "";
      return;
    }
    const steps = p.steps || [];
    const nSteps = pr && pr.steps !== undefined ? pr.steps : steps.length;
    const stepNo = pr && pr.step !== undefined ? Math.min(pr.step + 1, nSteps) : null;
    box.dataset.planId = String(p.plan_id);
    box.dataset.state = p.state;
    box.dataset.step = stepNo === null ? "" : String(stepNo);
    let title = "plan " + p.plan_id + " " + p.name + " (" + p.source + "): " + p.state;
    if (stepNo !== null && p.state === "running") {
      const s = steps[stepNo - 1];
      title += ", step " + stepNo + "/" + nSteps + (s ? " " + s.profile + " " + s.purpose : "");
      if (pr.attempt > 1) title += ", attempt " + pr.attempt;
      if (pr.waiting) title += ", waiting for the " + pr.waiting;
    }
    if (p.reason) title += " (" + p.reason + ")";
    $("plan-title").textContent = title;
    $("plan-trace").textContent = "operator " + traceText(p);

    // The steps: profile, purpose, the runs made for it.
    const ol = $("plan-steps");
    ol.innerHTML = "";
    const runs = (pr && pr.runs) || [];
    steps.forEach((s, i) => {
      const mine = runs.filter((r) => r.step === i + 1);
      const li = el("li", s.profile + " (" + s.purpose + ")" +
        (mine.length ? ": " + mine.map((r) => "run " + r.run_id + " " + r.units.join(" ")).join("; ") : ""));
      li.dataset.step = String(i + 1);
      if (p.state === "running" && stepNo === i + 1) li.className = "current";
      else if (stepNo !== null && i + 1 < stepNo) li.className = "done";
      ol.appendChild(li);
    });

    // The units: active or dropped, the verdict, and per step the measurements against the limits.
    const table = $("plan-units");
    const head = table.querySelector("thead");
    head.innerHTML = "";
    const hr = el("tr");
    ["unit", "in the plan", "verdict"].forEach((h) => hr.appendChild(el("th", h)));
    steps.forEach((s, i) => hr.appendChild(el("th", "step " + (i + 1) + " " + s.profile)));
    head.appendChild(hr);
    const body = table.querySelector("tbody");
    body.innerHTML = "";
    ((pr && pr.units) || []).forEach((u) => {
      const tr = el("tr", null, u.active ? "active" : "dropped");
      tr.dataset.serial = u.serial;
      tr.appendChild(el("td", u.serial));
      const reasons = (u.reasons || []).join("; ");
      tr.appendChild(el("td", u.active ? "active" : "dropped" + (reasons ? ": " + reasons : "")));
      const verdict = u.verdict || (u.marginal ? "marginal so far" : "pending");
      const vt = el("td", verdict, u.verdict || (u.marginal ? "marginal" : ""));
      vt.dataset.verdict = u.verdict || "";
      tr.appendChild(vt);
      steps.forEach((s, i) => {
        const ms = (u.measurements || []).filter((m) => m.step === i + 1);
        const td = el("td");
        td.dataset.step = String(i + 1);
        td.dataset.met = ms.length ? String(ms.every((m) => m.met)) : "";
        ms.forEach((m, k) => {
          if (k) td.appendChild(document.createTextNode(", "));
          const span = el("span", fmtValue(m) + (m.met ? " ok" : " NOT " + m.limit), m.met ? "pass" : (m.on_fail === "continue" ? "marginal" : "fail"));
          span.title = m.limit + " (line " + m.line + ", " + m.on_fail + ")" + (m.note ? ": " + m.note : "");
          if (m.axis) span.dataset.axis = m.axis;
          td.appendChild(span);
        });
        tr.appendChild(td);
      });
      body.appendChild(tr);
    });
  }

  // Who runs a plan and its units' lots (issue 24): "Ada, lots SIM-0001=L7 SIM-0002=L7".
  function lotsText(p) {
    const lots = Object.entries(p.lots || {}).map(([serial, lot]) => serial + "=" + lot);
    return lots.length ? lots.join(" ") : "-";
  }
  function traceText(p) {
    return (p.operator || "-") + ", lots " + lotsText(p);
  }

  function showQueue(q) {
    const body = $("queue").querySelector("tbody");
    body.innerHTML = "";
    const items = (q && q.queue) || [];
    $("queue").dataset.count = String(items.length);
    items.forEach((x) => {
      const tr = el("tr");
      tr.dataset.planId = String(x.plan_id);
      [x.position, x.plan_id, x.name, x.source, (x.units || []).join(" "), x.operator || "-", lotsText(x)]
        .forEach((t) => tr.appendChild(el("td", t)));
      body.appendChild(tr);
    });
    $("queue-empty").style.display = items.length ? "none" : "";
    showNext(items[0] || null);
  }

  // The queue's next plan, under the board: which units go into which slots, who runs it.
  function showNext(x) {
    const next = $("next");
    next.dataset.planId = x ? String(x.plan_id) : "";
    next.innerHTML = "";
    next.appendChild(el("strong", "Next: "));
    if (!x) {
      next.appendChild(document.createTextNode("nothing queued"));
      return;
    }
    next.appendChild(document.createTextNode("plan " + x.plan_id + " " + x.name + " (" + x.source + "): "));
    (x.units || []).forEach((serial, i) => {
      if (i) next.appendChild(document.createTextNode(", "));
      const slot = (x.slots || {})[serial];
      const u = el("span", (slot ? "slot " + slot + " " : "") + serial, "next-unit");
      u.dataset.serial = serial;
      u.dataset.slot = slot || "";
      next.appendChild(u);
    });
    next.appendChild(document.createTextNode("; operator " + traceText(x)));
  }

  async function refreshPlan() {
    if (busy || !window.fogPanel) return;
    busy = true;
    try {
      const st = await fogPanel.call({ cmd: "plan.status" });
      if (st.result) showPlan(st.result);
      else if (st.error && st.error.code === "not_found") showPlan(null);
      if (st.result || (st.error && st.error.code === "not_found")) {
        if (fogPanel.planShown) fogPanel.planShown(st.result || null);
      }
      const q = await fogPanel.call({ cmd: "queue.list" });
      if (q.result) showQueue(q.result);
    } catch (e) { /* reconnecting: panel.js reconnects, the next round refreshes */ }
    busy = false;
  }
  setInterval(refreshPlan, 2000);
  if (window.fogPanel) fogPanel.refreshPlan = refreshPlan;
  refreshPlan();
})();
