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
  let windowS = 10;          // the time traces' window [s of recording] (the layout's)
  const KEEP_S = 120;        // trace data kept, so the window can grow to this [s]
  const EST_WINDOW_S = 120;  // the estimates' window [s]
  // A feed whose data are this much older than the run's is stale [s of recording]: the
  // friction characterisation waits out each speed step's transient, so it is given longer.
  const STALE_S = { estimate: 2, cycle: 2, trace: 2, friction: 30, combustion: 2 };
  const ENVELOPE_BINS = 300; // display bins of a time trace (mean line, min–max band)
  const MAX_KEPT_EVENTS = 200000; // events kept for the export
  const CYCLES_SHOWN = 10;   // cycles overlaid in the cyclic view
  const RPM = 60 / (2 * Math.PI);
  const $ = (id) => document.getElementById(id);

  // What the page has received — also read by the browser test (window.physid).
  const st = {
    state: "connecting", t: NaN, samples: 0, estimates: 0, traces: 0, tracePoints: 0,
    cycles: 0, alarms: 0, lost: 0, hellos: 0, hello: null, last: {}, first: {},
    frictionCycles: 0, torqueCycles: 0, combustionCycles: 0, covImep: null, identifiability: {},
    twinWindows: 0, twinCalibrated: null, twinChannel: null,
    feeds: {}, stale: {}, layout: null, exported: 0,
  };
  window.physid = st;
  // Every event of the session as it came (the export), bounded.
  let kept = [];
  // The alarms raised, for the plots' markers: {param, t}.
  let alarmMarks = [];

  // The plots and the channels (series) each draws: the server's table too (crates/live/src/
  // layout.rs, PLOTS: a --layout file is checked against it; the browser test compares them).
  const PLOTS = {
    k: ["K"], b: ["B"], speed: ["omega_en", "omega_dy"], torque: ["torque_shaft", "torque_engine"],
    pint: ["p_int", "throttle"], cycles: ["torque_engine", "torque_shaft"], pcyl: ["p_cyl"],
    tcyc: ["torque_engine"], friction: ["measured", "predicted", "nominal", "truth"],
    combustion: ["imep", "mfb50_deg"],
  };
  st.plots = PLOTS;
  // For the browser test: the alarms marked on the plots, and a plot's uPlot.
  st.marks = () => alarmMarks;
  st.uplot = (id) => plots[id];

  let est, tr, cyc, means, fric, comb, combCurve, twinTrend;
  // The cycles the combustion trend and its CoV of IMEP cover.
  const COMBUSTION_SHOWN = 200;
  function reset() {
    fric = { cycle: [], measured: [], predicted: [], nominal: [], truth: [] };
    comb = { cycle: [], imep: [], mfb50: [] };
    combCurve = null;
    st.frictionCycles = 0; st.torqueCycles = 0; st.combustionCycles = 0; st.covImep = null;
    st.twinWindows = 0; st.twinCalibrated = null; st.twinChannel = null;
    twinTrend = { t: [], measured: {}, twin: {} };
    $("twin-channel").replaceChildren();
    st.identifiability = {};
    $("torque-table").tBodies[0].replaceChildren();
    $("ident").replaceChildren();
    $("friction-table").tBodies[0].replaceChildren();
    est = { t: [], K: [], Khi: [], Klo: [], B: [], Bhi: [], Blo: [] };
    tr = { t: [], omega_en: [], omega_dy: [], torque_shaft: [], torque_engine: [], p_int: [], throttle: [] };
    alarmMarks = []; st.feeds = {}; st.stale = {};
    updateBanner();
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
  function band(i, j, color) { return { series: [i, j], fill: color || "rgba(31,111,235,0.12)" }; }
  // Red marks at the alarms of `param`, drawn over the plot.
  function alarmMarker(param) {
    return {
      hooks: {
        draw: [(u) => {
          const ctx = u.ctx;
          ctx.save();
          ctx.strokeStyle = "#c62828"; ctx.fillStyle = "#c62828"; ctx.lineWidth = 2;
          ctx.setLineDash([5, 3]);
          ctx.font = "bold 12px system-ui";
          for (const m of alarmMarks) {
            if (m.param !== param) continue;
            const x = u.valToPos(m.t, "x", true);
            if (!(x >= u.bbox.left && x <= u.bbox.left + u.bbox.width)) continue;
            ctx.beginPath(); ctx.moveTo(x, u.bbox.top); ctx.lineTo(x, u.bbox.top + u.bbox.height); ctx.stroke();
            ctx.fillText("alarm", x + 3, u.bbox.top + 12);
          }
          ctx.restore();
        }],
      },
    };
  }
  function estPlot(id, param) {
    makePlot(id, [
      line(param, colors[0]),
      line("+3σ", "rgba(31,111,235,0.35)", { width: 1 }),
      line("−3σ", "rgba(31,111,235,0.35)", { width: 1 }),
      line("healthy high", "#2e7d32", { dash: [6, 4], width: 1 }),
      line("healthy low", "#2e7d32", { dash: [6, 4], width: 1 }),
    ], { uplot: { bands: [band(2, 3)], plugins: [alarmMarker(param)] } });
  }
  estPlot("plot-k", "K");
  estPlot("plot-b", "B");
  // A time trace per channel: the display bin's mean, and its min–max band (so a signal that
  // oscillates within a bin shows its envelope, not a comb).
  const TRACES = {
    speed: [["omega_en", "engine ω_en", colors[0]], ["omega_dy", "dynamometer ω_dy", colors[1]]],
    torque: [["torque_shaft", "shaft τ_shaft", colors[0]], ["torque_engine", "engine τ_engine", colors[2]]],
    pint: [["p_int", "p_int [kPa]", colors[3], "kPa"], ["throttle", "throttle [deg]", colors[4], "deg"]],
  };
  const tint = (c) => c + "26";
  function tracePlot(plot) {
    const series = [], bands = [];
    TRACES[plot].forEach(([, label, color, scale], k) => {
      const sc = scale ? { scale } : {};
      series.push(line(label, color, sc), line(label + " max", tint(color), Object.assign({ width: 0.5 }, sc)),
        line(label + " min", tint(color), Object.assign({ width: 0.5 }, sc)));
      bands.push(band(3 * k + 2, 3 * k + 3, tint(color)));
    });
    const uplot = { bands };
    if (plot === "pint") {
      // Each unit its own axis: kPa on the left, degrees on the right.
      uplot.scales = { x: { time: false }, kPa: {}, deg: {} };
      uplot.axes = [{ label: "t [s]" }, { scale: "kPa", label: "kPa", size: 60 },
        { scale: "deg", label: "deg", side: 1, size: 50, grid: { show: false } }];
    }
    makePlot("plot-" + plot, series, { uplot });
    // The legend names each channel once (its band's edges are not listed).
    const rows = plots["plot-" + plot].root.querySelectorAll(".u-legend .u-series");
    rows.forEach((row, i) => { if (i > 0 && (i - 1) % 3 !== 0) row.style.display = "none"; });
  }
  for (const plot in TRACES) tracePlot(plot);
  makePlot("plot-cycles", [line("engine torque, cycle mean", colors[2]), line("shaft torque, cycle mean", colors[0])],
    { xLabel: "cycle" });
  const fade = (k) => `rgba(31,111,235,${(0.15 + 0.85 * (k + 1) / CYCLES_SHOWN).toFixed(2)})`;
  const cycSeries = () => Array.from({ length: CYCLES_SHOWN }, (_, k) =>
    line(k === CYCLES_SHOWN - 1 ? "latest" : `−${CYCLES_SHOWN - 1 - k}`, fade(k), { width: k === CYCLES_SHOWN - 1 ? 2 : 1 }));
  const crankX = { xLabel: "crank angle from firing TDC [deg]", uplot: { scales: { x: { time: false, range: [-360, 360] } } } };
  makePlot("plot-pcyl", cycSeries(), crankX);
  makePlot("plot-tcyc", cycSeries(), crankX);
  // The twin: each window's mean of the chosen channel, measured and the twin's (the last
  // TWIN_WINDOWS windows: 30 s).
  const TWIN_WINDOWS = 600;
  makePlot("plot-twin", [line("measured", colors[0]), line("twin", colors[1], { dash: [6, 4] })],
    { uplot: { axes: [{ label: "t [s]" }, { size: 80 }] } });
  $("twin-channel").addEventListener("change", (ev) => { st.twinChannel = ev.target.value; touch(); });
  makePlot("plot-friction", [line("measured", colors[0]), line("predicted (before the cycle)", colors[1]),
    line("nominal model", colors[4], { dash: [6, 4] }), line("simulated truth", colors[2], { width: 1 })], { xLabel: "cycle" });
  // A scale at least `floor` wide about its data (a steady engine's IMEP varies by less than the
  // axis's labels can tell apart: shown flat, not magnified noise).
  const atLeast = (floor) => (u, lo, hi) => {
    if (lo == null || hi == null) return [lo, hi];
    const mid = (lo + hi) / 2, half = Math.max((hi - lo) / 2, floor(mid) / 2);
    return [mid - 1.1 * half, mid + 1.1 * half];
  };
  makePlot("plot-combustion", [line("IMEP [bar]", colors[0], { scale: "bar" }),
    line("MFB50 [deg ATDC]", colors[1], { scale: "deg" })], {
    xLabel: "cycle",
    uplot: {
      scales: {
        x: { time: false },
        bar: { range: atLeast((m) => Math.max(0.02 * Math.abs(m), 0.1)) },
        deg: { range: atLeast(() => 1) },
      },
      axes: [{ label: "cycle" }, { scale: "bar", label: "bar", size: 60 },
        { scale: "deg", label: "deg", side: 1, size: 50, grid: { show: false } }],
    },
  });
  // The latest cycle's pressure and heat release rate (a combustion event's curve).
  makePlot("plot-hrr", [line("pressure [bar]", colors[0], { scale: "bar" }),
    line("heat release rate [J/deg]", colors[3], { scale: "J" })], {
    xLabel: "crank angle from firing TDC [deg]",
    uplot: {
      scales: { x: { time: false, range: [-180, 180] }, bar: {}, J: {} },
      axes: [{ label: "crank angle from firing TDC [deg]" }, { scale: "bar", label: "bar", size: 60 },
        { scale: "J", label: "J/deg", side: 1, size: 50, grid: { show: false } }],
    },
  });
  // Which uPlot series draw each layout channel.
  function seriesOf(plot, channel) {
    const k = PLOTS[plot].indexOf(channel);
    if (TRACES[plot]) return [3 * k + 1, 3 * k + 2, 3 * k + 3];
    if (plot === "k" || plot === "b") return [1, 2, 3];
    if (plot === "pcyl" || plot === "tcyc") return Array.from({ length: CYCLES_SHOWN }, (_, i) => i + 1);
    return [k + 1];
  }
  const resize = () => {
    for (const id in plots) if ($(id).clientWidth > 0) plots[id].setSize({ width: Math.max(200, $(id).clientWidth), height: 210 });
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
    for (const plot in TRACES) plots["plot-" + plot].setData(envelopes(TRACES[plot].map(([ch]) => ch)));
    plots["plot-cycles"].setData([means.cycle, means.torque_engine, means.torque_shaft]);
    plots["plot-friction"].setData([fric.cycle, fric.measured, fric.predicted, fric.nominal, fric.truth]);
    const tc = st.twinChannel;
    plots["plot-twin"].setData([twinTrend.t, tc ? twinTrend.measured[tc] || [] : [], tc ? twinTrend.twin[tc] || [] : []]);
    plots["plot-combustion"].setData([comb.cycle, comb.imep, comb.mfb50]);
    if (combCurve) {
      // The grid runs from −360° ATDC; JSON's null (no heat release outside its window) stays a gap.
      const x = combCurve.p.map((_, k) => -360 + k * combCurve.step_deg);
      plots["plot-hrr"].setData([x, combCurve.p.map((v) => (v == null ? null : v * 1e-5)),
        combCurve.hrr.map((v) => (v == null ? null : v))]);
    }
    for (const [id, ch, scale] of [["plot-pcyl", "p_cyl", 1e-5], ["plot-tcyc", "torque_engine", 1]]) {
      const last = cyc.slice(-CYCLES_SHOWN);
      const newest = last.length ? last[last.length - 1] : null;
      const n = newest && newest[ch] ? newest[ch].length : 0;
      const step = newest ? newest.step_deg : 1;
      // The grid runs 0…720° from firing TDC; shown −360…360° so the TDC peak is whole.
      const half = Math.ceil(360 / step);
      const order = Array.from({ length: n }, (_, k) => (k + half) % n);
      const x = order.map((k) => (k * step >= 360 ? k * step - 720 : k * step));
      const ys = Array.from({ length: CYCLES_SHOWN }, (_, k) => {
        const c = last[k - (CYCLES_SHOWN - last.length)];
        return c && c[ch] ? order.map((i) => c[ch][i] * scale) : x.map(() => null);
      });
      plots[id].setData([x].concat(ys));
    }
  }
  // The traces within the window in ENVELOPE_BINS display bins: [t, then per channel mean,
  // max, min].
  function envelopes(channels) {
    const t1 = tr.t.length ? tr.t[tr.t.length - 1] : 0, t0 = t1 - windowS;
    let i0 = 0;
    while (i0 < tr.t.length && tr.t[i0] < t0) i0++;
    const width = windowS / ENVELOPE_BINS;
    const out = [[]].concat(channels.flatMap(() => [[], [], []]));
    let i = i0;
    while (i < tr.t.length) {
      const b = Math.floor((tr.t[i] - t0) / width);
      const end = t0 + (b + 1) * width;
      const acc = channels.map(() => [0, 0, -Infinity, Infinity]);
      let tsum = 0, n = 0;
      for (; i < tr.t.length && tr.t[i] < end; i++, n++) {
        tsum += tr.t[i];
        channels.forEach((ch, k) => {
          const v = tr[ch][i];
          if (v === null || !isFinite(v)) return;
          const a = acc[k]; a[0] += v; a[1]++; a[2] = Math.max(a[2], v); a[3] = Math.min(a[3], v);
        });
      }
      if (n === 0) { i++; continue; }
      out[0].push(tsum / n);
      acc.forEach((a, k) => {
        out[1 + 3 * k].push(a[1] ? a[0] / a[1] : null);
        out[2 + 3 * k].push(a[1] ? a[2] : null);
        out[3 + 3 * k].push(a[1] ? a[3] : null);
      });
    }
    return out;
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
  // A feed (estimate, cycle, trace, friction) delivered data of time t.
  function fed(feed, t) {
    if (!isFinite(t)) return;
    st.feeds[feed] = t;
    if (st.stale[feed] !== undefined) { delete st.stale[feed]; markStale(); }
  }
  // Cards whose data stopped while the run goes on say since when.
  function markStale() {
    document.querySelectorAll(".card[data-feed]").forEach((card) => {
      const since = st.stale[card.dataset.feed];
      card.classList.toggle("stale", since !== undefined);
      const tag = card.querySelector(".stale-tag");
      if (tag) tag.textContent = since !== undefined ? `stale since t = ${fmt(since, 2)} s` : "";
    });
  }
  function checkStale() {
    if (st.state !== "running") return;
    let changed = false;
    for (const feed in st.feeds) {
      const stale = st.t - st.feeds[feed] > (STALE_S[feed] || 2);
      if (stale && st.stale[feed] === undefined) { st.stale[feed] = st.feeds[feed]; changed = true; }
    }
    if (changed) markStale();
  }
  setInterval(checkStale, 500);
  // The banner: the oldest alarm not acknowledged, and how many.
  function updateBanner() {
    const open = Array.from($("alarms").querySelectorAll("tbody tr:not(.acked)"));
    $("alarm-count").textContent = String(open.length);
    const banner = $("alarm-banner");
    if (!open.length) { banner.hidden = true; return; }
    const oldest = open[open.length - 1];
    banner.hidden = false;
    banner.dataset.seq = oldest.dataset.seq;
    $("alarm-text").textContent = `ALARM ${oldest.dataset.param}: ${oldest.dataset.text}` +
      (open.length > 1 ? ` (+${open.length - 1} more not acknowledged)` : "");
  }

  const on = {
    hello(e) {
      reset();
      kept = kept.filter((k) => k.e.type === "hello").slice(-1);
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
      fed("estimate", e.t_s);
      $("k-now").textContent = `${fmt(p.K, 1)} ± ${fmt(3 * s.K, 1)}`;
      $("b-now").textContent = `${fmt(p.B, 4)} ± ${fmt(3 * s.B, 4)}`;
      touch();
    },
    alarm(e, seq) {
      st.alarms++; st.last.alarm = e; st.first.alarm = st.first.alarm || e; seen(e.t_s);
      const row = $("alarms").tBodies[0].insertRow(0);
      row.dataset.seq = seq; row.dataset.param = e.param;
      row.dataset.text = `${e.change < 0 ? "fell" : "rose"} ${fmt(100 * Math.abs(e.change), 1)} % from healthy at t = ${fmt(e.t_s, 2)} s`;
      alarmMarks.push({ param: e.param, t: e.t_s });
      row.insertCell().textContent = fmt(e.t_s, 3);
      row.insertCell().textContent = e.param;
      row.insertCell().textContent = `${100 * e.change >= 0 ? "+" : ""}${fmt(100 * e.change, 1)} %`;
      const b = document.createElement("button");
      b.textContent = "Ack"; b.className = "ack";
      b.onclick = () => post("ack", { seq: Number(seq) });
      row.insertCell().appendChild(b);
      updateBanner(); touch();
      log(`${fmt(e.t_s, 3)} s: alarm ${e.param}, ${e.change < 0 ? "fell" : "rose"} ${fmt(100 * Math.abs(e.change), 1)} % from healthy (left its bound at ${fmt(e.t_start_s, 3)} s)`, "error");
    },
    ack(e) {
      const row = $("alarms").querySelector(`tr[data-seq="${e.seq}"]`);
      if (row) { row.classList.add("acked"); const b = row.querySelector("button"); if (b) b.remove(); }
      updateBanner();
    },
    cycle(e) {
      st.cycles++; st.last.cycle = e; seen(e.t_s); fed("cycle", e.t_s);
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
      st.frictionCycles++; st.last.friction = e; fed("friction", e.t_s);
      if (!st.layout || (st.layout.plots.friction || []).length) show("friction-card");
      show("ident-card");
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
    // A cycle's combustion figures: the IMEP and MFB50 trend, the CoV of IMEP over the fired
    // cycles shown (sample standard deviation over the mean, as `physid cycles` gives it).
    combustion(e) {
      st.combustionCycles++; st.last.combustion = e; fed("combustion", e.t_s);
      if (!st.layout || (st.layout.plots.combustion || []).length) show("combustion-card");
      const f = e.figures || {};
      comb.cycle.push(e.cycle);
      comb.imep.push(f.imep == null ? null : f.imep * 1e-5);
      comb.mfb50.push(f.mfb50_deg ?? null);
      if (e.curve) { combCurve = e.curve; st.combustionCurveCycle = e.cycle; }
      if (comb.cycle.length > COMBUSTION_SHOWN) for (const k in comb) comb[k].shift();
      const fired = comb.imep.filter((v, i) => v !== null && comb.mfb50[i] !== null);
      if (fired.length >= 2) {
        const mean = fired.reduce((a, b) => a + b, 0) / fired.length;
        const sd = Math.sqrt(fired.reduce((a, b) => a + (b - mean) ** 2, 0) / (fired.length - 1));
        st.covImep = sd / Math.abs(mean);
        $("cov-imep").textContent = `CoV of IMEP ${fmt(100 * st.covImep, 2)} % over ${fired.length} fired cycles`;
      } else {
        st.covImep = null;
        $("cov-imep").textContent = fired.length ? "" : "no fired cycle";
      }
      touch();
    },
    // The twin's window: each channel's residual in units of its noise, each adapted
    // parameter now against its value when the twin started (the calibrated one).
    twin(e) {
      st.twinWindows++; st.last.twin = e; fed("twin", e.t_s);
      show("twin-card");
      if (!st.twinCalibrated) st.twinCalibrated = Object.assign({}, e.params);
      const res = $("twin-residual").tBodies[0];
      res.replaceChildren();
      for (const [ch, v] of Object.entries(e.residual)) {
        const r = res.insertRow();
        r.insertCell().textContent = ch;
        const c = r.insertCell();
        c.textContent = v === null ? "–" : fmt(v, 2);
        if (v !== null && v > 3) c.className = "bad";
      }
      // The trend of each channel's window means, the last TWIN_WINDOWS windows.
      const chans = Object.keys(e.measured || {});
      if (chans.length && !st.twinChannel) {
        st.twinChannel = chans.includes("omega_en") ? "omega_en" : chans[0];
        for (const ch of chans) {
          const o = document.createElement("option");
          o.textContent = ch; o.selected = ch === st.twinChannel;
          $("twin-channel").appendChild(o);
        }
      }
      if (chans.length) {
        twinTrend.t.push(e.t_s);
        for (const ch of chans) {
          (twinTrend.measured[ch] ||= []).push(e.measured[ch]);
          (twinTrend.twin[ch] ||= []).push(e.twin[ch]);
        }
        if (twinTrend.t.length > TWIN_WINDOWS) {
          twinTrend.t.shift();
          for (const ch of chans) { twinTrend.measured[ch].shift(); twinTrend.twin[ch].shift(); }
        }
      }
      const par = $("twin-params").tBodies[0];
      par.replaceChildren();
      for (const [p, v] of Object.entries(e.params)) {
        const r = par.insertRow();
        const cal = st.twinCalibrated[p];
        r.insertCell().textContent = p + ((e.frozen || []).includes(p) ? " (frozen)" : "");
        r.insertCell().textContent = Number(v).toPrecision(5);
        r.insertCell().textContent = Number(cal).toPrecision(5);
        r.insertCell().textContent = `${v >= cal ? "+" : ""}${fmt(100 * (v / cal - 1), 1)} %`;
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
      trimBefore(tr, e.t_s - KEEP_S);
      fed("trace", e.t_s);
      if (e.samples !== undefined) { st.samples = e.samples; $("samples").textContent = String(e.samples); }
      touch();
    },
    control(e) {
      st.last.control = e;
      let text = `${fmt(e.t_s, 3)} s: ${e.cmd}`;
      // A fault sent from this page: when it was stamped, and where the cell was when it came.
      if (e.cmd === "fault" && pendingFault) {
        text += ` ${pendingFault.spec} — acts at t = ${fmt(pendingFault.at, 3)} s (the page's time when sent); the cell was at t = ${fmt(e.t_s, 3)} s when it arrived`;
        pendingFault = null;
      }
      log(text);
      if (e.cmd === "pause") setState("paused");
      if (e.cmd === "resume") setState("running");
    },
    error(e) { log(`${fmt(e.t_s, 3)} s: ${e.input} line ${e.line}: ${e.message}`, "error"); },
    finding(e) {
      // Integrity findings (kind, sample) stand out: the data may be wrong.
      log(`${fmt(e.t_s, 3)} s: ${e.kind ? e.kind.replace(/_/g, " ") + " at sample " + e.sample + ": " : ""}${e.message}`, e.kind ? "error" : undefined);
    },
    end(e) {
      st.last.end = e; st.samples = e.samples; seen(e.t_s); setState("ended");
      st.stale = {}; markStale();
      $("samples").textContent = String(e.samples);
      log(`${fmt(e.t_s, 3)} s: end — ${e.samples} samples, ${e.dropped} frames dropped`);
    },
    log(e) {
      st.last.log = e;
      const mb = (e.bytes / 1048576).toFixed(2);
      $("log-status").textContent = e.state === "empty"
        ? `not written: ${e.file} — no sample came before the stop`
        : `${e.state === "recording" ? "recording" : "closed"}: ${e.file} — ${e.samples} samples, ${mb} MB`;
    },
    status(e) { $("clients").textContent = String(e.clients); $("lagged").textContent = `${st.lost} / ${e.lagged}`; },
    lagged(e) { st.lost += e.dropped; $("lagged").textContent = String(st.lost); log(`this page fell behind: ${e.dropped} events lost`, "error"); },
  };

  function connect() {
    const es = new EventSource(api("events"));
    es.onmessage = (m) => {
      let e;
      try { e = JSON.parse(m.data); } catch (err) { log(`unreadable event: ${err}`, "error"); return; }
      if (e.type !== "status") {
        kept.push({ seq: m.lastEventId, e });
        if (kept.length > MAX_KEPT_EVENTS) kept.splice(0, kept.length - MAX_KEPT_EVENTS);
      }
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
  // The fault sent last, until its control event comes back: its text and the time stamped.
  let pendingFault = null;
  submit("f-fault", async () => {
    let spec = $("fault-spec").value.trim();
    if (!spec) return;
    const at = isFinite(st.t) ? st.t : 0;
    if (!spec.includes("@")) spec += "@" + at;
    pendingFault = { spec, at: Number(spec.split("@")[1].split("+")[0]) };
    const j = await post("control", { cmd: "fault", spec });
    if (j.ok) $("reply").textContent = `fault: done — acts at t = ${fmt(pendingFault ? pendingFault.at : at, 2)} s (stamped by this page; the events say when it arrived)`;
    else pendingFault = null;
  });
  submit("f-scenario", () => post("control", { cmd: "scenario", name: $("scenario").value.trim() }));
  $("mode-speed").onclick = () => post("control", { cmd: "mode", demand: "speed" });
  $("mode-torque").onclick = () => post("control", { cmd: "mode", demand: "torque" });
  submit("f-log", () => post("control", { cmd: "record", file: $("log-file").value.trim() }));
  $("log-stop").onclick = () => post("control", { cmd: "record", stop: true });
  $("pause").onclick = () => post("control", { cmd: "pause" });
  $("resume").onclick = () => post("control", { cmd: "resume" });
  // Stop ends the run for every panel: it asks first.
  $("stop").onclick = () => { $("stop-confirm").hidden = false; };
  $("stop-no").onclick = () => { $("stop-confirm").hidden = true; };
  $("stop-yes").onclick = () => { $("stop-confirm").hidden = true; post("control", { cmd: "stop" }); };
  for (const b of document.querySelectorAll("button.restart")) {
    b.onclick = () => post("control", { cmd: "restart", stage: b.dataset.stage });
  }
  $("alarm-ack").onclick = () => {
    const banner = $("alarm-banner");
    if (!banner.hidden && banner.dataset.seq !== undefined) post("ack", { seq: Number(banner.dataset.seq) });
  };

  // ---- help and keys ----
  const help = (show) => { $("help").hidden = !show; };
  $("help-btn").onclick = () => help($("help").hidden);
  $("help-close").onclick = () => help(false);
  document.addEventListener("keydown", (ev) => {
    const tag = ev.target && ev.target.tagName;
    if (tag === "INPUT" || tag === "SELECT" || tag === "TEXTAREA" || ev.ctrlKey || ev.metaKey || ev.altKey) return;
    if (ev.key === "?") help($("help").hidden);
    else if (ev.key === "Escape") { help(false); $("stop-confirm").hidden = true; }
    else if (ev.key === "a") $("alarm-ack").click();
    else if (ev.key === "p") post("control", { cmd: st.state === "paused" ? "resume" : "pause" });
  });

  // ---- the session's events, exported ----
  function download(name, type, text) {
    const a = document.createElement("a");
    a.href = URL.createObjectURL(new Blob([text], { type }));
    a.download = name;
    document.body.appendChild(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  }
  const stamp = () => new Date().toISOString().replace(/[:.]/g, "-");
  // Traces are the plots' data: left out of the export (they are the recording's, decimated).
  const exported = () => kept.filter((k) => k.e.type !== "trace");
  function ndjson() { return exported().map((k) => JSON.stringify(Object.assign({ seq: Number(k.seq) }, k.e))).join("\n") + "\n"; }
  function csv() {
    const q = (v) => `"${String(v).replace(/"/g, '""')}"`;
    const rows = ["seq,type,t_s,summary,event"];
    for (const k of exported()) {
      const e = k.e;
      const summary = e.type === "alarm" ? `${e.param} ${fmt(100 * e.change, 1)} %`
        : e.type === "control" ? e.cmd : e.type === "error" || e.type === "finding" ? e.message
        : e.type === "estimate" ? `K ${fmt(e.params.K, 2)} B ${fmt(e.params.B, 4)}` : "";
      rows.push([k.seq, e.type, e.t_s ?? "", q(summary), q(JSON.stringify(e))].join(","));
    }
    return rows.join("\n") + "\n";
  }
  window.physidExport = { ndjson, csv };
  $("export-ndjson").onclick = () => { st.exported++; download(`physid-events-${stamp()}.ndjson`, "application/x-ndjson", ndjson()); };
  $("export-csv").onclick = () => { st.exported++; download(`physid-events-${stamp()}.csv`, "text/csv", csv()); };

  // ---- the layout: plots shown, channels drawn, the window ----
  const LAYOUT_KEY = "physid.layout";
  let fileLayout = null;
  function defaultLayout() {
    return { plots: JSON.parse(JSON.stringify(PLOTS)), window_s: 10 };
  }
  function applyLayout(layout) {
    const l = layout || defaultLayout();
    const shown = l.plots || PLOTS;
    st.layout = { plots: shown, window_s: l.window_s || 10 };
    windowS = st.layout.window_s;
    const sel = $("window");
    if (![...sel.options].some((o) => Number(o.value) === windowS)) sel.add(new Option(String(windowS)));
    sel.value = String(windowS);
    for (const plot in PLOTS) {
      const card = document.querySelector(`.card[data-plot="${plot}"]`);
      const on = shown[plot] || [];
      // The friction card appears with its data; the layout can only hide it.
      card.hidden = on.length === 0 || (plot === "friction" && !st.frictionCycles)
        || (plot === "combustion" && !st.combustionCycles);
      const u = plots["plot-" + plot];
      for (const ch of PLOTS[plot]) for (const i of seriesOf(plot, ch)) u.setSeries(i, { show: on.includes(ch) });
    }
    for (const box of document.querySelectorAll("#layout-picker input")) {
      box.checked = (shown[box.dataset.plot] || []).includes(box.dataset.channel);
    }
    resize(); touch();
  }
  function saveLayout() {
    localStorage.setItem(LAYOUT_KEY, JSON.stringify(st.layout));
  }
  function picker() {
    const box = $("layout-picker");
    for (const plot in PLOTS) {
      const fs = document.createElement("fieldset");
      const lg = document.createElement("legend");
      lg.textContent = plot;
      fs.appendChild(lg);
      for (const ch of PLOTS[plot]) {
        const label = document.createElement("label");
        const input = document.createElement("input");
        input.type = "checkbox"; input.dataset.plot = plot; input.dataset.channel = ch;
        input.onchange = () => {
          const plotsNow = JSON.parse(JSON.stringify(st.layout.plots));
          const on = new Set(plotsNow[plot] || []);
          if (input.checked) on.add(ch); else on.delete(ch);
          if (on.size) plotsNow[plot] = PLOTS[plot].filter((c) => on.has(c)); else delete plotsNow[plot];
          applyLayout({ plots: plotsNow, window_s: windowS });
          saveLayout();
        };
        label.append(input, " " + ch);
        fs.appendChild(label);
      }
      box.appendChild(fs);
    }
  }
  $("window").onchange = () => { applyLayout({ plots: st.layout.plots, window_s: Number($("window").value) }); saveLayout(); };
  $("layout-reset").onclick = () => { localStorage.removeItem(LAYOUT_KEY); applyLayout(fileLayout); };
  $("layout-save").onclick = () => download("physid-layout.json", "application/json", JSON.stringify(st.layout, null, 2) + "\n");
  async function loadLayout() {
    try {
      const r = await fetch(api("layout"));
      if (r.ok) fileLayout = await r.json();
    } catch (err) { /* the page's own layout */ }
    let mine = null;
    try { mine = JSON.parse(localStorage.getItem(LAYOUT_KEY) || "null"); } catch (err) { mine = null; }
    applyLayout(mine || fileLayout);
  }

  reset();
  picker();
  loadLayout();
  connect();
})();
