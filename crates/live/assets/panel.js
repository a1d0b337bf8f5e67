// physid live — the operator's panel. Reads the event stream (server-sent events from
// /api/events), draws with uPlot, posts the controls to /api/control. Every number arrives in
// SI units; the page shows speeds in rpm and pressures in kPa/bar, as labelled.
"use strict";
(() => {
  // The token, and on a fleet panel the cell this page shows (?cell=ID), go with every call.
  const query = new URLSearchParams(location.search);
  const pass = new URLSearchParams();
  for (const k of ["token", "cell"]) if (query.get(k)) pass.set(k, query.get(k));
  const api = (p) => "api/" + p + (pass.toString() ? "?" + pass.toString() : "");
  const WINDOW_S = 10;       // the time traces' rolling window [s of recording]
  const EST_WINDOW_S = 120;  // the estimates' window [s]
  const CYCLES_SHOWN = 10;   // cycles overlaid in the cyclic view
  const RPM = 60 / (2 * Math.PI);
  const $ = (id) => document.getElementById(id);

  // What the page has received — also read by the browser test (window.physid).
  const st = {
    state: "connecting", t: NaN, samples: 0, estimates: 0, traces: 0, tracePoints: 0,
    cycles: 0, alarms: 0, lost: 0, hellos: 0, hello: null, last: {}, first: {},
    frictionCycles: 0, torqueCycles: 0, identifiability: {},
  };
  window.physid = st;

  let est, tr, cyc, means, fric;
  function reset() {
    fric = { cycle: [], measured: [], predicted: [], nominal: [], truth: [] };
    st.frictionCycles = 0; st.torqueCycles = 0; st.identifiability = {};
    $("torque-table").tBodies[0].replaceChildren();
    $("ident").replaceChildren();
    $("friction-table").tBodies[0].replaceChildren();
    est = { t: [], K: [], Khi: [], Klo: [], B: [], Bhi: [], Blo: [] };
    tr = { t: [], omega_en: [], omega_dy: [], torque_shaft: [], torque_engine: [], p_int: [], throttle: [] };
    cyc = [];
    means = { cycle: [], torque_engine: [], torque_shaft: [] };
    $("alarms").tBodies[0].replaceChildren();
    $("log").replaceChildren();
    $("cycle-table").tBodies[0].replaceChildren();
    st.estimates = st.traces = st.tracePoints = st.cycles = st.alarms = 0;
    $("alarm-count").textContent = "0";
  }

  // ---- plots ----
  const plots = {};
  const colors = ["#1f6feb", "#d1242f", "#2e7d32", "#8250df", "#b26a00", "#0a7d8c"];
  function line(label, color, extra) {
    return Object.assign({ label, stroke: color, width: 1.5, points: { show: false } }, extra || {});
  }
  function makePlot(id, series, opts) {
    const el = $(id);
    const o = Object.assign({
      width: Math.max(200, el.clientWidth), height: 210,
      legend: { live: false }, cursor: { drag: { x: true, y: false } },
      scales: { x: { time: false } },
      series: [{ label: opts && opts.xLabel || "t [s]" }].concat(series),
      axes: [{ label: opts && opts.xLabel || "t [s]" }, { size: 60 }],
    }, opts && opts.uplot || {});
    const data = [[]].concat(series.map(() => []));
    plots[id] = new uPlot(o, data, el);
  }
  function band(i, j) { return { series: [i, j], fill: "rgba(31,111,235,0.12)" }; }
  function estPlot(id) {
    makePlot(id, [
      line("estimate", colors[0]),
      line("+3σ", "rgba(31,111,235,0.35)", { width: 1 }),
      line("−3σ", "rgba(31,111,235,0.35)", { width: 1 }),
      line("healthy high", "#2e7d32", { dash: [6, 4], width: 1 }),
      line("healthy low", "#2e7d32", { dash: [6, 4], width: 1 }),
    ], { uplot: { bands: [band(2, 3)] } });
  }
  estPlot("plot-k");
  estPlot("plot-b");
  makePlot("plot-speed", [line("engine ω_en", colors[0]), line("dynamometer ω_dy", colors[1])]);
  makePlot("plot-torque", [line("shaft τ_shaft", colors[0]), line("engine τ_engine", colors[2])]);
  makePlot("plot-pint", [line("p_int [kPa]", colors[3]), line("throttle [deg]", colors[4])]);
  makePlot("plot-cycles", [line("engine torque, cycle mean", colors[2]), line("shaft torque, cycle mean", colors[0])],
    { xLabel: "cycle" });
  const fade = (k) => `rgba(31,111,235,${(0.15 + 0.85 * (k + 1) / CYCLES_SHOWN).toFixed(2)})`;
  const cycSeries = () => Array.from({ length: CYCLES_SHOWN }, (_, k) =>
    line(k === CYCLES_SHOWN - 1 ? "latest" : `−${CYCLES_SHOWN - 1 - k}`, fade(k), { width: k === CYCLES_SHOWN - 1 ? 2 : 1 }));
  makePlot("plot-pcyl", cycSeries(), { xLabel: "crank angle [deg]" });
  makePlot("plot-tcyc", cycSeries(), { xLabel: "crank angle [deg]" });
  makePlot("plot-friction", [line("measured", colors[0]), line("predicted (before the cycle)", colors[1]),
    line("nominal model", colors[4], { dash: [6, 4] }), line("simulated truth", colors[2], { width: 1 })], { xLabel: "cycle" });
  const resize = () => {
    for (const id in plots) plots[id].setSize({ width: Math.max(200, $(id).clientWidth), height: 210 });
  };
  window.addEventListener("resize", resize);
  // Cards that only some runs fill (the friction characterisation) appear with their data.
  function show(id) {
    if ($(id).hidden) { $(id).hidden = false; resize(); }
  }

  let dirty = false;
  function redraw() {
    dirty = false;
    const h = st.hello && st.hello.healthy, b = st.hello ? st.hello.bound : NaN;
    const hl = (name) => [est.t.map(() => h ? h[name] * (1 + b) : null), est.t.map(() => h ? h[name] * (1 - b) : null)];
    const [khi, klo] = hl("K"), [bhi, blo] = hl("B");
    plots["plot-k"].setData([est.t, est.K, est.Khi, est.Klo, khi, klo]);
    plots["plot-b"].setData([est.t, est.B, est.Bhi, est.Blo, bhi, blo]);
    plots["plot-speed"].setData([tr.t, tr.omega_en, tr.omega_dy]);
    plots["plot-torque"].setData([tr.t, tr.torque_shaft, tr.torque_engine]);
    plots["plot-pint"].setData([tr.t, tr.p_int, tr.throttle]);
    plots["plot-cycles"].setData([means.cycle, means.torque_engine, means.torque_shaft]);
    plots["plot-friction"].setData([fric.cycle, fric.measured, fric.predicted, fric.nominal, fric.truth]);
    for (const [id, ch, scale] of [["plot-pcyl", "p_cyl", 1e-5], ["plot-tcyc", "torque_engine", 1]]) {
      const last = cyc.slice(-CYCLES_SHOWN);
      const n = last.length ? last[last.length - 1][ch] ? last[last.length - 1][ch].length : 0 : 0;
      const step = last.length ? last[last.length - 1].step_deg : 1;
      const x = Array.from({ length: n }, (_, k) => k * step);
      const ys = Array.from({ length: CYCLES_SHOWN }, (_, k) => {
        const c = last[k - (CYCLES_SHOWN - last.length)];
        return c && c[ch] ? c[ch].map((v) => v * scale) : x.map(() => null);
      });
      plots[id].setData([x].concat(ys));
    }
  }
  function touch() {
    if (!dirty) { dirty = true; requestAnimationFrame(redraw); }
  }

  // ---- events ----
  const fmt = (v, d) => (v === null || v === undefined || !isFinite(v)) ? "–" : Number(v).toFixed(d);
  function log(text, cls) {
    const li = document.createElement("li");
    li.textContent = text;
    if (cls) li.className = cls;
    const ol = $("log");
    ol.prepend(li);
    while (ol.children.length > 200) ol.lastChild.remove();
  }
  function setState(s) {
    st.state = s;
    const el = $("state");
    el.textContent = s;
    el.className = "pill " + s;
  }
  function trimBefore(obj, tmin) {
    let k = 0;
    while (k < obj.t.length && obj.t[k] < tmin) k++;
    if (k > 0) for (const key in obj) obj[key].splice(0, k);
  }
  function seen(t) {
    if (isFinite(t)) { st.t = t; $("t").textContent = fmt(t, 2); }
    if (st.state === "connecting" || st.state === "reconnecting") setState("running");
  }

  const on = {
    hello(e) {
      reset();
      st.first = {};
      st.hello = e; st.hellos++;
      $("source").textContent = e.source || "";
      const h = e.healthy || {};
      $("healthy").textContent = `K ${fmt(h.K, 0)}, B ${fmt(h.B, 3)}, ±${fmt(100 * e.bound, 0)} %`;
      setState(e.state || "running");
    },
    estimate(e) {
      st.estimates++; st.last.estimate = e; seen(e.t_s);
      const p = e.params, s = e.std_err || {};
      est.t.push(e.t_s);
      for (const name of ["K", "B"]) {
        const v = p[name], sd = s[name];
        est[name].push(v);
        est[name + "hi"].push(sd === null || sd === undefined ? null : v + 3 * sd);
        est[name + "lo"].push(sd === null || sd === undefined ? null : v - 3 * sd);
      }
      trimBefore(est, e.t_s - EST_WINDOW_S);
      $("k-now").textContent = `${fmt(p.K, 1)} ± ${fmt(3 * s.K, 1)}`;
      $("b-now").textContent = `${fmt(p.B, 4)} ± ${fmt(3 * s.B, 4)}`;
      touch();
    },
    alarm(e, seq) {
      st.alarms++; st.last.alarm = e; st.first.alarm = st.first.alarm || e; seen(e.t_s);
      const row = $("alarms").tBodies[0].insertRow(0);
      row.dataset.seq = seq; row.dataset.param = e.param;
      row.insertCell().textContent = fmt(e.t_s, 3);
      row.insertCell().textContent = e.param;
      row.insertCell().textContent = `${100 * e.change >= 0 ? "+" : ""}${fmt(100 * e.change, 1)} %`;
      const b = document.createElement("button");
      b.textContent = "Ack"; b.className = "ack";
      b.onclick = () => post("ack", { seq: Number(seq) });
      row.insertCell().appendChild(b);
      $("alarm-count").textContent = String($("alarms").querySelectorAll("tbody tr:not(.acked)").length);
      log(`${fmt(e.t_s, 3)} s: alarm ${e.param}, ${e.change < 0 ? "fell" : "rose"} ${fmt(100 * Math.abs(e.change), 1)} % from healthy (left its bound at ${fmt(e.t_start_s, 3)} s)`, "error");
    },
    ack(e) {
      const row = $("alarms").querySelector(`tr[data-seq="${e.seq}"]`);
      if (row) { row.classList.add("acked"); const b = row.querySelector("button"); if (b) b.remove(); }
      $("alarm-count").textContent = String($("alarms").querySelectorAll("tbody tr:not(.acked)").length);
    },
    cycle(e) {
      st.cycles++; st.last.cycle = e; seen(e.t_s);
      if (e.curve) { cyc.push(e.curve); if (cyc.length > CYCLES_SHOWN) cyc.shift(); }
      means.cycle.push(e.cycle);
      means.torque_engine.push(e.mean.torque_engine ?? null);
      means.torque_shaft.push(e.mean.torque_shaft ?? null);
      if (means.cycle.length > 300) for (const k in means) means[k].shift();
      const rows = [
        ["cycle", e.cycle, "", 0],
        ["speed", e.mean.omega_en * RPM, "rpm", 1],
        ["engine torque", e.mean.torque_engine, "N·m", 2],
        ["shaft torque", e.mean.torque_shaft, "N·m", 2],
        ["peak p_cyl", e.max.p_cyl * 1e-5, "bar", 2],
        ["at", e.max_deg.p_cyl, "deg", 1],
        ["p_int", e.mean.p_int * 1e-3, "kPa", 2],
      ];
      const body = $("cycle-table").tBodies[0];
      body.replaceChildren();
      for (const [name, v, unit, d] of rows) {
        const r = body.insertRow();
        r.insertCell().textContent = name; r.insertCell().textContent = fmt(v, d); r.insertCell().textContent = unit;
      }
      touch();
    },
    identifiability(e) {
      st.identifiability[e.app] = e; seen(e.t_s);
      show("ident-card");
      const box = $("ident");
      box.replaceChildren();
      for (const app of Object.keys(st.identifiability).sort()) {
        const x = st.identifiability[app];
        const p = document.createElement("p");
        p.dataset.app = app;
        const tag = (name, cls) => { const s = document.createElement("span"); s.className = "param " + cls; s.textContent = name; return s; };
        p.append(`${app}: `);
        for (const n of x.estimable) p.append(tag(n, "estimable"), " ");
        for (const n of x.frozen) p.append(tag(n, "frozen"), " ");
        box.appendChild(p);
      }
      log(`${fmt(e.t_s, 3)} s: ${e.app} estimates ${e.estimable.join(", ")}; frozen ${e.frozen.length ? e.frozen.join(", ") : "none"}`);
    },
    friction(e) {
      st.frictionCycles++; st.last.friction = e;
      show("friction-card"); show("ident-card");
      fric.cycle.push(e.cycle); fric.measured.push(e.measured); fric.predicted.push(e.predicted);
      fric.nominal.push(e.nominal); fric.truth.push(e.truth ?? null);
      if (fric.cycle.length > 1000) for (const k in fric) fric[k].shift();
      const body = $("friction-table").tBodies[0];
      body.replaceChildren();
      const err = 100 * (e.predicted - e.measured) / e.measured;
      for (const [name, v, s] of [["prediction error", err, null, "%"]].concat(Object.keys(e.params).map((n) => [n, e.params[n], e.std_err[n]]))) {
        const r = body.insertRow();
        r.insertCell().textContent = name;
        r.insertCell().textContent = s === null ? `${fmt(v, 2)} %` : `${Number(v).toPrecision(4)} ± ${isFinite(s) ? Number(3 * s).toPrecision(2) : "–"}`;
      }
      touch();
    },
    torque(e) {
      st.torqueCycles++; st.last.torque = e; seen(e.t_s);
      show("ident-card");
      const body = $("torque-table").tBodies[0];
      body.replaceChildren();
      const rows = [["cyclic torque: prediction error", `${fmt(100 * e.rms_error / e.rms_measured, 2)} % RMS`]]
        .concat(Object.keys(e.params).map((n) => [n, `${Number(e.params[n]).toPrecision(5)} ± ${Number(3 * e.std_err[n]).toPrecision(2)}`]));
      for (const [name, text] of rows) {
        const r = body.insertRow();
        r.insertCell().textContent = name; r.insertCell().textContent = text;
      }
    },
    trace(e) {
      st.traces++; st.tracePoints += e.t.length; seen(e.t_s);
      const c = e.channels;
      for (let k = 0; k < e.t.length; k++) {
        tr.t.push(e.t[k]);
        tr.omega_en.push(c.omega_en ? c.omega_en[k] * RPM : null);
        tr.omega_dy.push(c.omega_dy ? c.omega_dy[k] * RPM : null);
        tr.torque_shaft.push(c.torque_shaft ? c.torque_shaft[k] : null);
        tr.torque_engine.push(c.torque_engine ? c.torque_engine[k] : null);
        tr.p_int.push(c.p_int ? c.p_int[k] * 1e-3 : null);
        tr.throttle.push(c.throttle ? c.throttle[k] : null);
      }
      trimBefore(tr, e.t_s - WINDOW_S);
      touch();
    },
    control(e) { st.last.control = e; log(`${fmt(e.t_s, 3)} s: ${e.cmd}`); if (e.cmd === "pause") setState("paused"); if (e.cmd === "resume") setState("running"); },
    error(e) { log(`${fmt(e.t_s, 3)} s: ${e.input} line ${e.line}: ${e.message}`, "error"); },
    finding(e) {
      // Integrity findings (kind, sample) stand out: the data may be wrong.
      log(`${fmt(e.t_s, 3)} s: ${e.kind ? e.kind.replace(/_/g, " ") + " at sample " + e.sample + ": " : ""}${e.message}`, e.kind ? "error" : undefined);
    },
    end(e) {
      st.last.end = e; st.samples = e.samples; seen(e.t_s); setState("ended");
      $("samples").textContent = String(e.samples);
      log(`${fmt(e.t_s, 3)} s: end — ${e.samples} samples, ${e.dropped} frames dropped`);
    },
    log(e) {
      st.last.log = e;
      const mb = (e.bytes / 1048576).toFixed(2);
      $("log-status").textContent = `${e.state === "recording" ? "recording" : "closed"}: ${e.file} — ${e.samples} samples, ${mb} MB`;
    },
    status(e) { $("clients").textContent = String(e.clients); $("lagged").textContent = `${st.lost} / ${e.lagged}`; },
    lagged(e) { st.lost += e.dropped; $("lagged").textContent = String(st.lost); log(`this page fell behind: ${e.dropped} events lost`, "error"); },
  };

  function connect() {
    const es = new EventSource(api("events"));
    es.onmessage = (m) => {
      let e;
      try { e = JSON.parse(m.data); } catch (err) { log(`unreadable event: ${err}`, "error"); return; }
      const f = on[e.type];
      if (f) f(e, m.lastEventId);
    };
    es.onerror = () => {
      // The browser reconnects by itself; the server greets again with hello and the backlog.
      if (st.state !== "ended") setState("reconnecting");
    };
  }

  // ---- controls ----
  async function post(path, body) {
    const reply = $("reply");
    try {
      const r = await fetch(api(path), {
        method: "POST",
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify(body),
      });
      const j = await r.json();
      reply.className = "reply " + (j.ok ? "ok" : "err");
      reply.textContent = j.ok ? `${j.cmd || "ack"}: done` : j.error;
      return j;
    } catch (err) {
      reply.className = "reply err";
      reply.textContent = String(err);
      return { ok: false, error: String(err) };
    }
  }
  window.physidControl = post;
  const submit = (id, f) => $(id).addEventListener("submit", (ev) => { ev.preventDefault(); f(); });
  // A number field's value, or nothing sent and the reason shown: an empty field is not 0.
  function number(id, what) {
    const text = $(id).value.trim();
    const v = Number(text);
    if (text === "" || !isFinite(v)) {
      const reply = $("reply");
      reply.className = "reply err";
      reply.textContent = text === "" ? `${what}: enter a number (nothing was sent)` : `${what}: '${text}' is not a number (nothing was sent)`;
      return null;
    }
    return v;
  }
  submit("f-speed", () => {
    const rpm = number("speed", "speed demand");
    if (rpm !== null) post("control", { cmd: "speed", rpm });
  });
  submit("f-throttle", () => {
    const deg = number("throttle", "throttle");
    if (deg !== null) post("control", { cmd: "throttle", deg });
  });
  submit("f-fault", () => {
    let spec = $("fault-spec").value.trim();
    if (!spec) return;
    if (!spec.includes("@")) spec += "@" + (isFinite(st.t) ? st.t : 0);
    post("control", { cmd: "fault", spec });
  });
  submit("f-scenario", () => post("control", { cmd: "scenario", name: $("scenario").value.trim() }));
  $("mode-speed").onclick = () => post("control", { cmd: "mode", demand: "speed" });
  $("mode-torque").onclick = () => post("control", { cmd: "mode", demand: "torque" });
  submit("f-log", () => post("control", { cmd: "record", file: $("log-file").value.trim() }));
  $("log-stop").onclick = () => post("control", { cmd: "record", stop: true });
  $("pause").onclick = () => post("control", { cmd: "pause" });
  $("resume").onclick = () => post("control", { cmd: "resume" });
  $("stop").onclick = () => post("control", { cmd: "stop" });

  reset();
  connect();
})();
