// physid fleet — every cell of the fleet from /api/fleet, once a second; a cell's name opens
// its live view (the operator's panel on ?cell=ID). Numbers arrive in SI units.
"use strict";
(() => {
  const query = new URLSearchParams(location.search);
  const token = query.get("token");
  const withToken = (params) => {
    if (token) params.set("token", token);
    return params.toString();
  };
  const $ = (id) => document.getElementById(id);
  const st = { polls: 0, cells: [], error: null };
  window.physidFleet = st;  // read by the browser test
  const fmt = (v, e) => (v == null ? "–" : e == null ? v.toPrecision(5) : `${v.toPrecision(5)} ± ${e.toPrecision(2)}`);
  const cellText = (c) => {
    const est = c.estimate || {};
    const p = est.params || {}, s = est.std_err || {};
    const a = c.last_alarm;
    return [
      c.state, c.source || "–", c.rate_hz == null ? "–" : c.rate_hz.toFixed(0),
      est.t_s == null ? "–" : est.t_s.toFixed(2), fmt(p.K, s.K), fmt(p.B, s.B), String(c.alarms),
      a ? `${a.param} ${(100 * a.change).toFixed(1)} % at ${a.t_s.toFixed(2)} s` : "–", String(c.errors),
    ];
  };
  // Rows are kept and updated in place, keyed by cell: a row the operator is pointing at,
  // selecting text in or clicking is never swapped under them by the next poll.
  const rows = new Map();
  const row = (c) => {
    let tr = rows.get(c.cell);
    if (!tr) {
      tr = document.createElement("tr");
      tr.dataset.cell = c.cell;
      const link = document.createElement("a");
      link.href = "?" + withToken(new URLSearchParams({ cell: c.cell }));
      link.textContent = c.cell;
      const first = document.createElement("td");
      first.append(link);
      tr.append(first, ...cellText(c).map(() => document.createElement("td")));
      rows.set(c.cell, tr);
    }
    tr.className = c.alarms > 0 ? "alarm" : "";
    cellText(c).forEach((t, i) => {
      const td = tr.cells[i + 1];
      if (td.textContent !== t) td.textContent = t;
    });
    return tr;
  };
  const render = (cells) => {
    const body = document.querySelector("#cells tbody");
    const shown = cells.map(row);
    const now = new Set(cells.map((c) => c.cell));
    for (const [cell, tr] of rows) {
      if (!now.has(cell)) {
        tr.remove();
        rows.delete(cell);
      }
    }
    // A row is moved only when it is out of order.
    shown.forEach((tr, i) => {
      if (body.rows[i] !== tr) body.insertBefore(tr, body.rows[i] || null);
    });
    $("n").textContent = cells.length;
    $("running").textContent = cells.filter((c) => c.state === "running").length;
    $("alarms").textContent = cells.reduce((n, c) => n + c.alarms, 0);
  };
  const poll = async () => {
    try {
      const params = withToken(new URLSearchParams());
      const r = await fetch("api/fleet" + (params ? "?" + params : ""));
      const v = await r.json();
      if (!r.ok) throw new Error(v.error || r.statusText);
      st.cells = v.cells;
      st.polls += 1;
      st.error = null;
      render(v.cells);
      $("state").textContent = "live";
    } catch (e) {
      st.error = String(e);
      $("state").textContent = "no answer: " + e;
    }
  };
  poll();
  setInterval(poll, 1000);
})();
