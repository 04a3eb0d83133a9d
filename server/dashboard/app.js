// sandswim's dashboard: one page that reads the daemon's REST API (/api/v1) and its live feed.
// Paths are the links a user pastes into a notebook: /, /campaign-runs/ID, /sweeps/ID, /runs/ID,
// /beds, /beds/ID, /submit, /campaigns, /campaigns/NAME[?version=N], /campaigns/NAME/edit and
// /new-campaign[?from=BASE]. Plots are uPlot (the one npm package, pinned, served by the daemon).
//
// Live: GET /api/v1/live/events (server-sent events, read with fetch so that a token can be sent)
// pushes one shared snapshot per change; past the daemon's stream limit, or when the stream fails,
// the page polls GET /api/v1/live every 2 s with its ETag. A page asks for more only when a run
// it shows finishes (that run's own row), so its cost does not grow with ticks.
'use strict';

// The token: sandswimd prints the dashboard's link with ?token=...; the page keeps it for this tab
// (sessionStorage) and takes it out of the address bar and the history at once.
(function takeTokenFromAddress() {
  const params = new URLSearchParams(location.search);
  if (!params.has('token')) return;
  sessionStorage.setItem('sandswim-token', (params.get('token') || '').trim());
  params.delete('token');
  const rest = params.toString();
  history.replaceState(history.state, '', location.pathname + (rest ? `?${rest}` : '') + location.hash);
})();

const $ = (sel, root = document) => root.querySelector(sel);

// Widths come as data-width: the daemon's Content-Security-Policy drops style attributes, so they
// are set through the CSSOM whenever such elements appear in the page.
function applyWidths(node) {
  if (node.nodeType !== 1) return;
  if (node.dataset.width) node.style.width = node.dataset.width;
  for (const el of node.querySelectorAll('[data-width]')) el.style.width = el.dataset.width;
}
new MutationObserver(records => { for (const r of records) r.addedNodes.forEach(applyWidths); })
  .observe(document.documentElement, { childList: true, subtree: true });
const main = () => $('#main');

// ---- Formatting ---------------------------------------------------------------------------------

function esc(v) {
  return String(v ?? '').replace(/[&<>"']/g, c => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' })[c]);
}
function num(v, digits = 3) {
  if (v === null || v === undefined || Number.isNaN(v)) return '';
  if (v === 0) return '0';
  const a = Math.abs(v);
  return a >= 1e4 || a < 1e-3 ? v.toExponential(digits - 1) : Number(v.toPrecision(digits)).toString();
}
function when(t) {
  if (!t) return '';
  const d = new Date(t * 1000), p = n => String(n).padStart(2, '0');
  return `${d.getFullYear()}-${p(d.getMonth() + 1)}-${p(d.getDate())} ${p(d.getHours())}:${p(d.getMinutes())}:${p(d.getSeconds())}`;
}
function duration(s) {
  if (s === null || s === undefined || !isFinite(s)) return 'unknown';
  if (s < 90) return `${Math.round(s)} s`;
  if (s < 5400) return `${Math.round(s / 60)} min`;
  if (s < 172800) return `${(s / 3600).toFixed(1)} h`;
  return `${(s / 86400).toFixed(1)} d`;
}
function stateBadge(state) { return `<span class="state state-${esc(state)}">${esc(state)}</span>`; }
function pointText(p) {
  if (!p) return '';
  const parts = [esc(p.mode)];
  for (const k of ['A', 'f', 'Omega', 'omega']) if (p[k] !== undefined && p[k] !== null && p[k] !== 0) parts.push(`${k}=${num(p[k])}`);
  if (p.axis && p.omega) parts.push(`axis ${esc(p.axis)}`);
  return parts.join(' ');
}

// The ETA's band as the daemon gives it (low_s..high_s: s/e^r..s*e^r, a log-scale band, not
// symmetric), or computed so from rel_error when a daemon sends none; '' without an error.
function etaBandText(eta) {
  let low = eta.low_s, high = eta.high_s;
  const r = eta.rel_error || 0;
  if (!(typeof high === 'number' && high > 0) && r > 0) { low = eta.s / Math.exp(r); high = eta.s * Math.exp(r); }
  return typeof high === 'number' && high > 0 ? ` (${duration(low)} – ${duration(high)})` : '';
}

// Counts -> a bar and a line of text with the daemon's ETA (server/store/cost_model.h: what is left at
// the engine rates it measured, from the first heartbeats; its 1-sigma band; its basis on hover).
function progressHtml(counts, eta) {
  const c = Object.assign({ done: 0, running: 0, queued: 0, failed: 0, cancelled: 0 }, counts || {});
  const total = c.done + c.running + c.queued + c.failed + c.cancelled;
  const pct = k => total ? (100 * c[k] / total).toFixed(2) : 0;
  const remaining = c.queued + c.running;
  let etaText = '';
  if (remaining > 0) {
    etaText = eta && typeof eta.s === 'number'
      ? ` · <span data-role="eta" title="${esc(eta.basis || '')}">ETA ${duration(eta.s)}${etaBandText(eta)}</span>`
      : ' · ETA unknown';
  }
  return `<div class="progress" title="${c.done} done, ${c.running} running, ${c.queued} queued, ${c.failed} failed">` +
    ['done', 'running', 'failed', 'cancelled'].map(k => `<span class="p-${k}" data-width="${pct(k)}%"></span>`).join('') +
    `</div><div class="progress-text" data-role="progress-text">${c.done} done · ${c.running} running · ${c.queued} queued · ` +
    `${c.failed} failed${c.cancelled ? ` · ${c.cancelled} cancelled` : ''}${etaText}</div>`;
}

// ---- The API ------------------------------------------------------------------------------------

function token() { return sessionStorage.getItem('sandswim-token') || ''; }
// An API address for an image or a link, which cannot send the Authorization header: the token
// goes as ?access_token= (reads only; the daemon sends no Referer onwards).
function authed(path) {
  return token() ? `${path}${path.includes('?') ? '&' : '?'}access_token=${encodeURIComponent(token())}` : path;
}
function headers(extra = {}) {
  const h = Object.assign({}, extra);
  if (token()) h.Authorization = `Bearer ${token()}`;
  return h;
}
class ApiError extends Error {
  constructor(status, problem) {
    super(problem && problem.detail ? problem.detail : `HTTP ${status}`);
    this.status = status;
    this.problem = problem || {};
  }
}
async function api(path, options = {}) {
  const res = await fetch(path, Object.assign({}, options, { headers: headers(options.headers || {}) }));
  const text = await res.text();
  let body = null;
  try { body = text ? JSON.parse(text) : null; } catch (e) { body = { detail: text }; }
  if (!res.ok) throw new ApiError(res.status, body);
  return { body, res };
}
const get = async path => (await api(path)).body;
// A results read whole (GET .../results is paged): the first page holding the rows of every page,
// their `next` paths followed, and the aggregates of every page, each point once (a page has those
// of the points of its runs: a point whose runs two pages share is on both, the same; known by the
// smallest run id among its values).
async function getResults(path) {
  const all = await get(`${path}?limit=10000`);
  const pointOf = a => Math.min(...(a.values || []).map(v => v.run_id));
  all.aggregates = all.aggregates || [];
  const points = new Set(all.aggregates.map(pointOf));
  for (let next = all.next; next; ) {
    const page = await get(next);
    all.results.push(...page.results);
    for (const a of page.aggregates || []) {
      if (!points.has(pointOf(a))) { points.add(pointOf(a)); all.aggregates.push(a); }
    }
    next = page.results.length ? page.next : null;
  }
  delete all.next;
  delete all.next_cursor;
  return all;
}
async function post(path, body) {
  return api(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: typeof body === 'string' ? body : JSON.stringify(body) });
}

function say(text, ok = false) {
  const box = $('#action-message');
  box.textContent = text;
  box.className = 'action-message' + (ok ? ' ok' : '');
  box.hidden = false;
}
function refusal(err) {
  if (err.status === 401) return `Refused (401): ${err.message}. Open the link sandswimd printed when it started (…/?token=…), or paste the daemon's token (the file token in its --data directory) in the token box above, and try again.`;
  return `Refused (${err.status || 'network'}): ${err.message}`;
}

// ---- Live feed ----------------------------------------------------------------------------------

const live = { snapshot: null, listeners: new Set(), etag: null, mode: 'connecting' };

function setLiveStatus(mode, why = '') {
  live.mode = mode;
  const el = $('#live-status');
  el.textContent = { live: 'live', polling: 'live (polling)', offline: 'offline: retrying', connecting: 'connecting…' }[mode];
  el.className = `live-status ${mode}`;
  el.title = why || el.title;
}
function publish(snapshot) {
  if (live.snapshot && snapshot.version === live.snapshot.version) return;
  live.snapshot = snapshot;
  for (const fn of live.listeners) {
    try { fn(snapshot); } catch (e) { console.warn('live update', e); }
  }
}
function onLive(fn) {
  live.listeners.add(fn);
  if (live.snapshot) fn(live.snapshot);
}

// The stream is closed when the page goes (a browser keeps only a few connections per host open;
// a stream left behind would hold one).
const liveStop = new AbortController();
window.addEventListener('pagehide', () => liveStop.abort());

async function streamLive() {
  const res = await fetch('/api/v1/live/events', { headers: headers({ Accept: 'text/event-stream' }), signal: liveStop.signal });
  if (!res.ok || !res.body) throw new ApiError(res.status, null);
  setLiveStatus('live', 'server-sent events');
  const reader = res.body.getReader();
  const decoder = new TextDecoder();
  let buffer = '';
  for (;;) {
    const { value, done } = await reader.read();
    if (done) throw new Error('the stream ended');
    buffer += decoder.decode(value, { stream: true });
    let end;
    while ((end = buffer.indexOf('\n\n')) >= 0) {
      const block = buffer.slice(0, end);
      buffer = buffer.slice(end + 2);
      const data = block.split('\n').filter(l => l.startsWith('data: ')).map(l => l.slice(6)).join('\n');
      if (data) publish(JSON.parse(data));
    }
  }
}
async function pollLive() {
  const res = await fetch('/api/v1/live', { headers: headers(live.etag ? { 'If-None-Match': live.etag } : {}) });
  if (res.status === 304) return;
  if (!res.ok) throw new ApiError(res.status, null);
  live.etag = res.headers.get('ETag');
  publish(await res.json());
}
async function runLive() {
  for (;;) {
    try {
      await streamLive();
    } catch (e) {
      // 503: every stream the daemon allows is open; poll. Otherwise the daemon may be restarting.
      const until = Date.now() + (e.status === 503 ? 60000 : 10000);
      while (Date.now() < until) {
        try {
          await pollLive();
          setLiveStatus('polling', e.status === 503 ? 'the daemon\'s stream limit is reached' : String(e.message));
        } catch (err) {
          setLiveStatus('offline', `the daemon does not answer (${err.message}); retrying`);
        }
        await new Promise(r => setTimeout(r, 2000));
      }
    }
  }
}

// ---- Tables that sort and filter ---------------------------------------------------------------

// columns: [{key, label, num?, html?(row)->string, value?(row)->sortable}]. Shows at most `limit`
// matching rows at first (a "show all" button for the rest), so a 10,000-run page renders fast.
function dataTable(container, columns, rows, { filterPlaceholder = 'filter…', limit = 500, rowId = null } = {}) {
  const state = { rows, sortKey: null, dir: 1, filter: '', limit };
  container.innerHTML = `<div class="table-tools"><input type="search" class="table-filter" placeholder="${esc(filterPlaceholder)}">` +
    `<span class="muted table-count"></span><button class="show-all" hidden>show all</button></div>` +
    `<div class="table-wrap"><table><thead><tr>${columns.map(c => `<th class="sortable" data-key="${esc(c.key)}">${esc(c.label)}</th>`).join('')}</tr></thead><tbody></tbody></table></div>`;
  const tbody = $('tbody', container);
  const valueOf = (c, r) => (c.value ? c.value(r) : r[c.key]);
  const textOf = r => columns.map(c => { const v = valueOf(c, r); return v === null || v === undefined ? '' : String(v); }).join(' ').toLowerCase();
  function render() {
    let shown = state.rows;
    if (state.filter) {
      const words = state.filter.toLowerCase().split(/\s+/).filter(Boolean);
      shown = shown.filter(r => { const t = textOf(r); return words.every(w => t.includes(w)); });
    }
    if (state.sortKey) {
      const c = columns.find(x => x.key === state.sortKey);
      shown = shown.slice().sort((a, b) => {
        const va = valueOf(c, a), vb = valueOf(c, b);
        if (va === vb) return 0;
        if (va === null || va === undefined || va === '') return 1;
        if (vb === null || vb === undefined || vb === '') return -1;
        return (va < vb ? -1 : 1) * state.dir;
      });
    }
    const visible = shown.slice(0, state.limit);
    tbody.innerHTML = visible.map(r => `<tr${rowId ? ` data-id="${esc(rowId(r))}"` : ''}>` + columns.map(c =>
      `<td${c.num ? ' class="num"' : ''} data-key="${esc(c.key)}">${c.html ? c.html(r) : esc(valueOf(c, r))}</td>`).join('') + '</tr>').join('');
    $('.table-count', container).textContent = visible.length < shown.length
      ? `showing ${visible.length} of ${shown.length} (${state.rows.length} in all)` : `${shown.length} of ${state.rows.length}`;
    $('.show-all', container).hidden = visible.length >= shown.length;
    for (const th of container.querySelectorAll('th')) {
      th.classList.toggle('sorted-asc', th.dataset.key === state.sortKey && state.dir > 0);
      th.classList.toggle('sorted-desc', th.dataset.key === state.sortKey && state.dir < 0);
    }
  }
  $('.table-filter', container).addEventListener('input', e => { state.filter = e.target.value; render(); });
  $('.show-all', container).addEventListener('click', () => { state.limit = Infinity; render(); });
  for (const th of container.querySelectorAll('th')) {
    th.addEventListener('click', () => {
      state.dir = state.sortKey === th.dataset.key ? -state.dir : 1;
      state.sortKey = th.dataset.key;
      render();
    });
  }
  render();
  return { setRows(r) { state.rows = r; render(); }, rows: () => state.rows, render };
}

// ---- Navigation: a page's late answers and plots end with it -----------------------------------

// Bumped at every client-side navigation; a page's code checks it after each await (current()).
const nav = { generation: 0, plots: [] };  // plots: the page's uPlot instances
function leavePage() {
  nav.generation++;
  live.listeners.clear();
  for (const p of nav.plots.splice(0)) p.destroy();
}
const current = generation => generation === nav.generation;
const keepPlot = p => { nav.plots.push(p); return p; };

// ---- Plots (uPlot) -------------------------------------------------------------------------------

// Axis labels to their needed digits (uPlot's default rounds small steps, 0.0015 to "0.002").
const tickValues = (u, splits) => splits.map(v => (v === null ? '' : String(+v.toPrecision(6))));

const palette = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#17becf', '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22'];

// Points with vertical error bars (half-widths `err`), and optional law curves: hover shows values.
function uzPlot(el, { xLabel, yLabel, x, y, err, curves = [], title }) {
  const xs = [...new Set([...x, ...curves.flatMap(c => c.x)])].sort((a, b) => a - b);
  const at = new Map(xs.map((v, i) => [v, i]));
  const column = (px, py) => { const a = new Array(xs.length).fill(null); px.forEach((v, i) => { a[at.get(v)] = py[i]; }); return a; };
  const yCol = column(x, y), errCol = column(x, err.map(e => e ?? null));
  const data = [xs, yCol, ...curves.map(c => column(c.x, c.y))];
  const series = [{ label: xLabel }, { label: `${yLabel} (±95 %)`, stroke: palette[0], paths: () => null, points: { show: true, size: 8, fill: palette[0] },
    value: (u, v, si, i) => (v === null ? '—' : `${num(v)} ± ${num(errCol[i])}`) }]
    .concat(curves.map((c, i) => ({ label: c.label, stroke: palette[(i + 1) % palette.length], width: 1.5, spanGaps: true, points: { show: false } })));
  const errorBars = u => {
    const ctx = u.ctx;
    ctx.save();
    ctx.strokeStyle = palette[0];
    ctx.lineWidth = 1.5 * devicePixelRatio;
    for (let i = 0; i < xs.length; i++) {
      if (yCol[i] === null || errCol[i] === null) continue;
      const px = Math.round(u.valToPos(xs[i], 'x', true));
      const lo = u.valToPos(yCol[i] - errCol[i], 'y', true), hi = u.valToPos(yCol[i] + errCol[i], 'y', true);
      ctx.beginPath();
      ctx.moveTo(px, lo); ctx.lineTo(px, hi);
      ctx.moveTo(px - 4, lo); ctx.lineTo(px + 4, lo);
      ctx.moveTo(px - 4, hi); ctx.lineTo(px + 4, hi);
      ctx.stroke();
    }
    ctx.restore();
  };
  const ys = yCol.map((v, i) => (v === null ? null : [v - (errCol[i] || 0), v + (errCol[i] || 0)])).filter(Boolean).flat();
  const yMin = Math.min(0, ...ys, ...curves.flatMap(c => c.y)), yMax = Math.max(0, ...ys, ...curves.flatMap(c => c.y));
  const pad = (yMax - yMin) * 0.08 || 0.01;
  return keepPlot(new uPlot({
    title, width: Math.min(el.clientWidth || 640, 900), height: 320, series, data,
    scales: { x: { time: false }, y: { range: [yMin - pad, yMax + pad] } },
    axes: [{ label: xLabel, values: tickValues }, { label: yLabel, size: 70, values: tickValues }],
    hooks: { draw: [errorBars] },
  }, data, el));
}

// z(t) of several runs (each its own times), on one plot: hover shows each run's z.
function trajectoriesPlot(el, runs, { title = 'z(t) of the SO' } = {}) {
  const xs = [...new Set(runs.flatMap(r => r.t))].sort((a, b) => a - b);
  const at = new Map(xs.map((v, i) => [v, i]));
  const data = [xs, ...runs.map(r => { const a = new Array(xs.length).fill(null); r.t.forEach((t, i) => { a[at.get(t)] = r.z[i]; }); return a; })];
  const series = [{ label: 't (s)', value: (u, v) => (v === null ? '—' : num(v, 4)) }]
    .concat(runs.map((r, i) => ({ label: r.label, stroke: palette[i % palette.length], width: 1.4, spanGaps: true, points: { show: false },
      value: (u, v) => (v === null ? '—' : `${num(v, 4)} m`) })));
  return keepPlot(new uPlot({ title, width: Math.min(el.clientWidth || 640, 900), height: 320, series, data,
    scales: { x: { time: false } }, axes: [{ label: 't (s)', values: tickValues }, { label: 'z (m)', size: 80, values: tickValues }] }, data, el));
}

function decimate(t, z, max = 800) {
  if (t.length <= max) return { t, z };
  const step = Math.ceil(t.length / max), T = [], Z = [];
  for (let i = 0; i < t.length; i += step) { T.push(t[i]); Z.push(z[i]); }
  T.push(t[t.length - 1]); Z.push(z[z.length - 1]);
  return { t: T, z: Z };
}

// ---- Result rows (sweep and campaign-run pages) -------------------------------------------------

const flagText = r => [r.precision_met ? 'target met' : '', r.broke_surface ? 'broke surface' : '', r.near_floor ? 'near floor' : '',
  r.conclusive === false ? 'inconclusive' : '', r.trending ? 'trend' : ''].filter(Boolean).join(', ');
// The material parameters some row sets (`fields`: the results' material_fields), one column each;
// a row without the field has Table 1's value (the API carries only those that are not).
function materialColumns(fields, rows) {
  return (fields || []).filter(f => rows.some(r => r[f.name] !== undefined)).map(f => ({
    key: f.name, label: f.unit ? `${f.name} (${f.unit})` : f.name, num: true,
    value: r => r[f.name] ?? f.table1, html: r => num(r[f.name] ?? f.table1) }));
}
function resultColumns(withSweeps, results) {
  const cols = [
    { key: 'run_id', label: 'run', num: true, html: r => `<a href="/runs/${r.run_id}">${r.run_id}</a>` },
    { key: 'mode', label: 'mode' },
    { key: 'A', label: 'A (m)', num: true, html: r => num(r.A) },
    { key: 'f', label: 'f (Hz)', num: true, html: r => num(r.f) },
    { key: 'Omega', label: 'Ω (rad/s)', num: true, html: r => num(r.Omega) },
    { key: 'omega', label: 'ω (rad/s)', num: true, html: r => num(r.omega) },
    ...materialColumns(results && results.material_fields, (results && results.results) || []),
    { key: 'replicate', label: 'bed', num: true },
    { key: 'state', label: 'state', html: r => stateBadge(r.state) + (r.progress ? ` <span class="muted">${esc(r.progress)}</span>` : '') },
    { key: 'Uz', label: 'U_z (m/s)', num: true, html: r => esc(r.Uz_text || ''), value: r => r.Uz },
    { key: 'dz', label: 'Δz (m)', num: true, html: r => num(r.dz) },
    { key: 'flags', label: 'flags', value: r => flagText(r), html: r => esc(flagText(r)) + (r.inconclusive_reason ? ` <span class="muted" title="${esc(r.inconclusive_reason)}">(why?)</span>` : '') },
  ];
  if (withSweeps) cols.push({ key: 'sweeps', label: 'sweeps', value: r => (r.sweeps || []).join(' '), html: r => esc((r.sweeps || []).join(', ')) });
  return cols;
}

// Keeps a results table in step with the live feed: running runs show their simulated time; a run
// that stops running is read once (its own row) and its row replaced.
function followRows(table) {
  let running = new Set(table.rows().filter(r => r.state === 'running').map(r => r.run_id));
  onLive(async snap => {
    const now = new Map((snap.running || []).map(r => [r.id, r]));
    const rows = table.rows();
    const byId = new Map(rows.map(r => [r.run_id, r]));
    let changed = false;
    for (const [id, r] of now) {
      const row = byId.get(id);
      if (!row) continue;
      row.state = 'running';
      row.progress = `${num(r.progress.sim_time_s)} of ${num(r.run_duration_s)} s`;
      changed = true;
    }
    const finished = [...running].filter(id => !now.has(id) && byId.has(id));
    running = new Set([...now.keys()].filter(id => byId.has(id)));
    for (const id of finished) {
      try {
        const run = await get(`/api/v1/runs/${id}`);
        const row = byId.get(id);
        row.state = run.state;
        row.progress = '';
        const res = run.result || {};
        Object.assign(row, { Uz: res.uz ?? null, Uz_text: (res.uz_text || '').replace(' m/s', ''), dz: res.dz ?? null, conclusive: res.conclusive,
          inconclusive_reason: res.inconclusive_reason || '', precision_met: res.precision_met, broke_surface: res.broke_surface, near_floor: res.near_floor,
          trending: res.trending });
        changed = true;
      } catch (e) { console.warn('run', id, e); }
    }
    if (changed) table.render();
  });
}

// U_z against the swept parameter, per sweep: the point aggregates (over replicate beds) with their
// 95 % intervals, and the fitted law when the daemon fitted one.
async function sweepUzPlot(el, sweep) {
  const axes = (sweep.spec && sweep.spec.axes) || [];
  const param = axes.length === 1 ? axes[0].param : null;
  if (!param) { el.innerHTML = '<p class="muted">No single swept parameter: no U_z curve.</p>'; return false; }
  const generation = nav.generation;
  // Every page: a page carries the aggregates of its own points only.
  const [results, fits] = await Promise.all([getResults(`/api/v1/sweeps/${sweep.id}/results`), get(`/api/v1/sweeps/${sweep.id}/fits`).catch(() => null)]);
  if (!current(generation)) return false;
  const pts = (results.aggregates || []).filter(a => a.uz_mean !== undefined && a.conclusive > 0);
  if (!pts.length) { el.innerHTML = `<p class="muted">${esc(sweep.name)}: no conclusive U_z yet.</p>`; return false; }
  // A swept material: a point at Table 1's value does not carry the field (material_fields says it).
  const material = (results.material_fields || []).find(f => f.name === param);
  const x = pts.map(a => a[param] ?? (material ? material.table1 : undefined)), y = pts.map(a => a.uz_mean), err = pts.map(a => a.uz_ci95 ?? null);
  const xLabel = material && material.unit ? `${param} (${material.unit})` : param;
  const curves = [];
  for (const b of (fits && fits.branches) || []) {
    const lo = Math.min(...x), hi = Math.max(...x), grid = Array.from({ length: 60 }, (_, i) => lo + (hi - lo) * i / 59);
    if (b.saturation && param === 'Omega') {
      const s = b.saturation, xs = grid.filter(v => (b.omega_sign < 0 ? v < 0 : v > 0));  // its side of Omega = 0, as the daemon says
      curves.push({ label: `fit (${b.branch}): C1=${num(s.C1)}±${num(s.C1_stderr)} m/s`, x: xs, y: xs.map(v => s.sign * s.C1 * (1 - Math.exp(-s.C2 * Math.abs(v)))) });
    }
    if (b.linear && param === 'A') {
      const l = b.linear, xs = grid.filter(v => v >= l.A_from && v <= l.A_to);
      curves.push({ label: `fit: C3=${num(l.C3)}±${num(l.C3_stderr)} 1/s`, x: xs, y: xs.map(v => l.C3 * v) });
    }
  }
  uzPlot(el, { title: `${sweep.name}: U_z against ${param}`, xLabel, yLabel: 'U_z (m/s)', x, y, err, curves });
  return true;
}

// The daemon's own U_z figure of a sweep (PLplot, as in the report), once it has a conclusive U_z
// to draw (before that the daemon answers 422).
const uzFigure = (sweep, caption) => `<figure><img class="figure" loading="lazy" alt="U_z of sweep ${esc(sweep.name)}" ` +
  `src="${esc(authed(`/api/v1/sweeps/${sweep.id}/uz.svg`))}"><figcaption>${esc(caption)}</figcaption></figure>`;

// ---- Pages --------------------------------------------------------------------------------------

async function overviewPage() {
  document.title = 'sandswim';
  main().innerHTML = `<h1>Campaigns and sweeps</h1>
    <section class="card"><h2>Campaign runs</h2><div id="campaign-runs"></div></section>
    <section class="card"><h2>Sweeps</h2><div id="sweeps"></div></section>
    <section class="card"><h2>Run a campaign again</h2><div id="campaigns" class="muted">Loading…</div></section>`;
  get('/api/v1/campaigns').then(r => {
    const list = r.campaigns || [];
    $('#campaigns').innerHTML = (list.length ? list.map(c => `<p><a href="/campaigns/${encodeURIComponent(c.name)}"><b>${esc(c.name)}</b></a> (${esc(c.scale || '')}${c.builtin ? ', built-in' : `, version ${esc(c.version)}`}) ` +
      `<button class="rerun" data-campaign="${esc(c.name)}">Run ${esc(c.name)} now</button> <span class="muted">${describe(c)}</span></p>`).join('')
      : '<p>No campaigns.</p>') + '<p><a href="/campaigns">All campaigns</a>: their versions, runs and schedules; make your own copy of one, or <a href="/new-campaign">write a new one</a>.</p>';
    for (const b of document.querySelectorAll('button.rerun')) b.addEventListener('click', () => rerunCampaign(b.dataset.campaign));
  }).catch(e => { $('#campaigns').textContent = e.message; });
  const crTable = dataTable($('#campaign-runs'), [
    { key: 'id', label: 'id', num: true, html: r => `<a href="/campaign-runs/${r.id}">${r.id}</a>` },
    { key: 'campaign', label: 'campaign', html: r => `<a href="/campaigns/${encodeURIComponent(r.campaign)}">${esc(r.campaign)}</a>` },
    { key: 'scale', label: 'scale' }, { key: 'trigger', label: 'trigger' },
    { key: 'created_at', label: 'started', html: r => esc(when(r.created_at)) },
    { key: 'progress', label: 'progress', value: r => r.counts.done, html: r => progressHtml(r.counts, r.eta) },
  ], [], { rowId: r => r.id });
  const swTable = dataTable($('#sweeps'), [
    { key: 'id', label: 'id', num: true, html: r => `<a href="/sweeps/${r.id}">${r.id}</a>` },
    { key: 'name', label: 'name' }, { key: 'scale', label: 'scale' },
    { key: 'campaign_run_id', label: 'campaign run', html: r => (r.campaign_run_id ? `<a href="/campaign-runs/${r.campaign_run_id}">${r.campaign_run_id}</a>` : '') },
    { key: 'created_at', label: 'submitted', html: r => esc(when(r.created_at)) },
    { key: 'progress', label: 'progress', value: r => r.counts.done, html: r => progressHtml(r.counts, r.eta) + (r.cancelled ? ' <span class="state state-cancelled">cancelled</span>' : '') },
  ], [], { rowId: r => r.id });
  onLive(snap => { crTable.setRows(snap.campaign_runs || []); swTable.setRows(snap.sweeps || []); });
}

async function rerunCampaign(name) {
  try {
    const { body } = await post('/api/v1/sweeps', { campaign: name });
    say(`Campaign ${name} submitted: campaign run ${body.id} (${body.runs} runs, ${body.runs_new} new).`, true);
    history.pushState(null, '', `/campaign-runs/${body.id}`);
    route();
  } catch (e) { say(refusal(e)); }
}

// The rounds of an adaptive campaign run (server/jobs/rounds.h; `adaptive` and `rounds` of GET
// /api/v1/campaign-runs/{id}), as `sandswim status cr:ID` prints them: one row a round -- its
// state, what it added and why, core-h planned and spent, the budget left after it, each claim's
// state after its look (a decided one frozen at the round whose look decided it) -- and why the
// rounds stopped. Every server string is escaped.
function roundsHtml(adaptive, rounds) {
  const h = v => (typeof v === 'number' ? esc(num(v)) : '–');
  const a = adaptive || {};
  let html = `<p>Budget ${h(a.budget_core_h)} core-h, at most ${h(a.max_rounds)} rounds. Core-hours at the cost model's ` +
    `rates: planned prices each run at its maximum length, spent counts the simulated time done runs took.</p>`;
  if (!rounds || !rounds.length) {
    return html + '<p class="muted" id="rounds-stop">Round 1 (what was submitted) is recorded at the daemon\'s next scheduler tick.</p>';
  }
  const after = r => Array.isArray(r.claims_after)
    ? r.claims_after.map(c => `<span class="state verdict-${esc(c.verdict)}" data-claim="${esc(c.claim)}">${esc(c.claim)} ${esc(c.verdict)}` +
      `${c.frozen_at_round !== undefined && c.frozen_at_round !== null ? ` (frozen at round ${esc(c.frozen_at_round)})` : ''}</span>`).join(' ')
    : '<span class="muted">after its runs are done</span>';
  html += '<table id="rounds-table"><thead><tr><th>round</th><th>state</th><th>what it added, and why</th><th>core-h planned</th>' +
    '<th>core-h spent</th><th>budget left</th><th>the claims after it</th></tr></thead><tbody>' +
    rounds.map(r => {
      const state = r.stop_reason ? 'stopped' : typeof r.finished_at === 'number' ? 'finished' : 'running';
      const added = (r.actions || []).map(x => `<li>${esc(x.reason)}</li>`).join('');
      return `<tr data-round="${esc(r.round)}"><td class="num">${esc(r.round)}</td><td>${stateBadge(state)}</td>` +
        `<td class="wrap">${added ? `<ul class="reasons">${added}</ul>` : '<span class="muted">nothing</span>'}</td>` +
        `<td class="num">${h(r.core_h_planned)}</td><td class="num">${h(r.core_h_spent)}</td><td class="num">${h(r.budget_left_core_h)}</td>` +
        `<td class="wrap">${after(r)}</td></tr>`;
    }).join('') + '</tbody></table>';
  const last = rounds[rounds.length - 1];
  return html + (typeof last.stop_reason === 'string'
    ? `<p id="rounds-stop"><b>Stopped after round ${esc(last.round)}:</b> ${esc(last.stop_reason)}</p>`
    : `<p id="rounds-stop" class="muted">Round ${esc(last.round)} runs; the daemon looks at the claims once its runs are done.</p>`);
}

async function campaignRunPage(id) {
  document.title = `campaign run ${id} · sandswim`;
  const generation = nav.generation;
  const [info, results] = await Promise.all([get(`/api/v1/campaign-runs/${id}`), getResults(`/api/v1/campaign-runs/${id}/results`)]);
  if (!current(generation)) return;
  main().innerHTML = `<h1>Campaign run ${id}: <a href="/campaigns/${encodeURIComponent(info.campaign)}">${esc(info.campaign)}</a>${info.campaign_version ? ` version ${esc(info.campaign_version)}` : ''} at ${esc(info.scale)}</h1>
    <section class="card"><dl class="facts"><dt>started</dt><dd>${esc(when(info.created_at))} (${esc(info.trigger)})</dd>
      <dt>progress</dt><dd id="progress">${progressHtml(info.counts, info.eta)}</dd>
      <dt>sweeps</dt><dd>${info.sweeps.map(s => `<a href="/sweeps/${s}">${s}</a>`).join(', ')}</dd>
      ${info.last_drift && info.last_drift.summary ? `<dt>drift</dt><dd class="wrap" id="drift">${esc(info.last_drift.summary)}</dd>` : ''}
      <dt>report</dt><dd><a href="${esc(authed(`/api/v1/campaign-runs/${id}/report`))}">the HTML report</a> · <a href="${esc(authed(`/api/v1/campaign-runs/${id}/results?format=csv`))}">results as CSV</a></dd></dl></section>
    <section class="card"><h2>The paper's findings: do they hold here?</h2><p class="muted help-link"><a href="/help/docs/explanation/verdicts.md">What a verdict means, and how often it is wrong</a></p><div id="claims" class="muted">Loading…</div></section>
    ${info.adaptive ? `<section class="card"><h2>Rounds</h2><p class="muted help-link"><a href="/help/docs/how-to/adaptive-campaigns.md#seeing-the-rounds">Reading the rounds</a></p><div id="rounds">${roundsHtml(info.adaptive, info.rounds)}</div></section>` : ''}
    <section class="card"><h2>Runs</h2><div id="runs"></div></section>
    <section class="card"><h2>U_z against the swept parameter</h2><div id="uz-plots" class="grid2"></div>
      <h2>Figures</h2><div id="figures" class="grid2"></div></section>`;
  const table = dataTable($('#runs'), resultColumns(true, results), results.results || [], { filterPlaceholder: 'filter runs (e.g. "Omega done", "inconclusive")', rowId: r => r.run_id });
  performance.mark('runs-table');  // the page's first render with its runs (tests/bench/bench_dashboard.cc)
  followRows(table);
  // An adaptive run's rounds as the live feed counts them: when the daemon has planned a round or
  // taken a look, the page reads them (and the claims, which a look may have frozen) again.
  const roundsKey = r => `${r.rounds} rounds, ${r.looks} looks${r.stopped ? ', stopped' : ''}`;
  const list = info.rounds || [];
  let roundsSeen = roundsKey({ rounds: list.length, looks: list.filter(r => typeof r.finished_at === 'number').length,
    stopped: list.some(r => typeof r.stop_reason === 'string') });
  onLive(snap => {
    const mine = (snap.campaign_runs || []).find(c => c.id === id);
    if (mine) $('#progress').innerHTML = progressHtml(mine.counts, mine.eta);
    if (!info.adaptive || !mine || !mine.rounds || roundsKey(mine.rounds) === roundsSeen) return;
    const seen = roundsKey(mine.rounds);
    // A look also changes its runs: a new round's join the table, a longer run takes its point's place.
    // Seen only once read: a failed read is tried again at the next live message.
    Promise.all([get(`/api/v1/campaign-runs/${id}`), getResults(`/api/v1/campaign-runs/${id}/results`)]).then(([now, rows]) => {
      if (!current(generation)) return;
      roundsSeen = seen;
      $('#rounds').innerHTML = roundsHtml(now.adaptive, now.rounds);
      table.setRows(rows.results || []);
      showClaims();
    }).catch(e => { if (current(generation)) $('#rounds-stop').textContent = `The rounds could not be read again: ${e.message}`; });
  });
  // The claims' verdicts: drawn again after each look of an adaptive run's rounds.
  const showClaims = () => get(`/api/v1/campaign-runs/${id}/claims`).then(c => {
    if (!current(generation)) return;
    $('#claims').classList.remove('muted');
    const n = c.counts || {};
    // A verdict's error rates at this design (core/claim_rates.h), or "not calibrated at this design".
    const rates = r => r ? `<div class="rates${r.calibrated ? '' : ' uncalibrated'}${r.low_power ? ' low-power' : ''}">${esc(r.text)}${r.advice ? ` — ${esc(r.advice)}` : ''}</div>` : '';
    const parts = v => (v.parts || []).length ? `<details class="parts"><summary>${v.parts.length} part(s)</summary><ul>` +
      v.parts.map(p => `<li><span class="state verdict-${esc(p.verdict)}">${esc(p.verdict)}</span> ${esc(p.name)}: ${esc(p.reason)}${rates(p.rates)}</li>`).join('') + '</ul></details>' : '';
    $('#claims').innerHTML = `<p>${n.holds || 0} hold · ${n.differs || 0} differ · ${n.inconclusive || 0} inconclusive. ${esc(c.note || '')}` +
      `${!c.design_text ? '' : c.adaptive ? ` Design: ${esc(c.design_text)}; an open claim is inconclusive until a look decides it.` : ` Error rates at this design: ${esc(c.design_text)}, measured on the truth engine.`}</p><table id="claims-table"><thead><tr><th>claim</th><th>verdict</th><th>error rates at this design</th><th>why</th></tr></thead><tbody>` +
      (c.claims || []).map(v => `<tr><td title="${esc(v.paper && v.paper.text)}"><b>${esc(v.id)}</b> ${esc(v.title)}</td>` +
        `<td><span class="state verdict-${esc(v.verdict)}">${esc(v.verdict_text || v.verdict)}</span></td><td class="wrap">${rates(v.rates)}</td><td class="wrap">${esc(v.reason)}${parts(v)}</td></tr>`).join('') + '</tbody></table>';
  }).catch(e => { if (current(generation)) $('#claims').textContent = `No verdicts: ${e.message}`; });
  showClaims();
  const plots = $('#uz-plots'), figures = $('#figures');
  for (const sid of info.sweeps) {
    const sweep = await get(`/api/v1/sweeps/${sid}`);
    if (!current(generation)) return;
    const div = document.createElement('div');
    div.className = 'plot';
    plots.appendChild(div);
    const drawn = await sweepUzPlot(div, sweep).catch(e => { div.textContent = `${sweep.name}: ${e.message}`; return false; });
    if (!current(generation)) return;
    if (drawn) figures.insertAdjacentHTML('beforeend', uzFigure(sweep, `${sweep.name} (the daemon's figure)`));
  }
  if ((results.results || []).some(r => r.mode !== 'oscillatory' && r.state === 'done')) {
    figures.insertAdjacentHTML('beforeend', `<figure><img class="figure" loading="lazy" alt="modes" src="${esc(authed(`/api/v1/campaign-runs/${id}/modes.svg`))}"><figcaption>the drive modes (paper Fig. 2)</figcaption></figure>`);
  }
  if (!figures.children.length) figures.innerHTML = '<p class="muted">The daemon draws its figures once runs have finished with a conclusive U_z.</p>';
}

async function sweepPage(id) {
  document.title = `sweep ${id} · sandswim`;
  const generation = nav.generation;
  const [sweep, results] = await Promise.all([get(`/api/v1/sweeps/${id}`), getResults(`/api/v1/sweeps/${id}/results`)]);
  if (!current(generation)) return;
  main().innerHTML = `<h1>Sweep ${id}: ${esc(sweep.name)} <span class="muted">(${esc(sweep.scale)})</span></h1>
    <section class="card"><dl class="facts"><dt>submitted</dt><dd>${esc(when(sweep.created_at))}${sweep.campaign_run_id ? ` in <a href="/campaign-runs/${sweep.campaign_run_id}">campaign run ${sweep.campaign_run_id}</a>` : ''}</dd>
      <dt>progress</dt><dd id="progress">${progressHtml(sweep.counts, sweep.eta)}</dd>
      <dt></dt><dd><button id="cancel" class="danger" ${sweep.cancelled ? 'disabled' : ''}>${sweep.cancelled ? 'cancelled' : 'Cancel this sweep'}</button>
      <a href="${esc(authed(`/api/v1/sweeps/${id}/results?format=csv`))}">results as CSV</a></dd></dl></section>
    <section class="card"><h2>Runs</h2><div id="runs"></div></section>
    <section class="card grid2"><div><h2>U_z</h2><div id="uz-plot" class="plot"></div></div><div><h2>z(t)</h2><div id="zt-plot" class="plot"></div></div></section>
    <section class="card"><h2>The daemon's figures</h2><div class="grid2" id="figures">${sweep.counts.done > 0
      ? `<figure><img class="figure" alt="trajectories" loading="lazy" src="${esc(authed(`/api/v1/sweeps/${id}/trajectories.svg`))}"><figcaption>Δz(t) of every run</figcaption></figure>`
      : '<p class="muted">Drawn once runs have finished.</p>'}</div></section>`;
  const table = dataTable($('#runs'), resultColumns(false, results), results.results || [], { rowId: r => r.run_id });
  followRows(table);
  $('#cancel').addEventListener('click', async () => {
    try {
      const { body } = await post(`/api/v1/sweeps/${id}/cancel`, {});
      say(`Sweep ${id} cancelled: ${body.cancel ? JSON.stringify(body.cancel) : ''}`, true);
      $('#cancel').disabled = true;
    } catch (e) { say(refusal(e)); }
  });
  onLive(snap => {
    const mine = (snap.sweeps || []).find(s => s.id === id);
    if (mine) $('#progress').innerHTML = progressHtml(mine.counts, mine.eta);
  });
  sweepUzPlot($('#uz-plot'), sweep).then(drawn => {
    if (drawn && current(generation)) $('#figures').insertAdjacentHTML('afterbegin', uzFigure(sweep, 'U_z (the daemon\'s figure, as in the report)'));
  }).catch(e => { $('#uz-plot').textContent = e.message; });
  const done = (results.results || []).filter(r => r.state === 'done').slice(0, 12);
  const runs = await Promise.all(done.map(r => get(`/api/v1/runs/${r.run_id}`)));
  if (!current(generation)) return;
  const series = runs.filter(r => r.trajectory && r.trajectory.t.length).map(r => Object.assign(decimate(r.trajectory.t, r.trajectory.z), { label: `run ${r.id}: ${pointText(r.point)}` }));
  if (series.length) trajectoriesPlot($('#zt-plot'), series);
  else $('#zt-plot').innerHTML = '<p class="muted">No finished run yet.</p>';
}

async function runPage(id) {
  document.title = `run ${id} · sandswim`;
  const generation = nav.generation;
  let run = await get(`/api/v1/runs/${id}`);
  if (!current(generation)) return;
  const render = () => {
    const res = run.result;
    const err = run.last_error;
    main().innerHTML = `<h1>Run ${id} <span id="run-state">${stateBadge(run.state)}</span></h1>
      <section class="card"><dl class="facts"><dt>point</dt><dd>${esc(pointText(run.point))}</dd>
        <dt>bed</dt><dd><a href="/beds/${run.bed_id}">bed ${run.bed_id}</a></dd>
        <dt>sweeps</dt><dd>${(run.sweeps || []).map(s => `<a href="/sweeps/${s}">${s}</a>`).join(', ')}</dd>
        <dt>attempts</dt><dd>${run.attempts}${run.worker ? ` · worker ${esc(run.worker)}` : ''}</dd>
        <dt>progress</dt><dd><span class="bar"><span id="sim-bar" data-width="0%"></span></span> <span id="sim-time"></span></dd>
        ${err ? `<dt>failure</dt><dd id="failure" class="error">${esc(err.kind)}: ${esc(err.message || err.reason || JSON.stringify(err))}</dd>` : ''}
      </dl></section>
      <section class="card"><h2>z(t) of the SO</h2><div id="zt-plot" class="plot"></div><p class="muted" id="zt-note"></p></section>
      ${res ? `<section class="card"><h2>Result</h2><p class="muted help-link"><a href="/help/docs/explanation/uz.md">How U_z and its error are measured</a></p><dl class="facts" id="result">
        <dt>U_z</dt><dd><b>${esc(res.uz_text || '')}</b></dd>
        <dt>window</dt><dd>${num(res.window_t0)} – ${num(res.window_t1)} s, ${res.uz_blocks} ${esc(res.block_kind || 'block')}s, ends at ${esc(res.window_end)}</dd>
        <dt>Δz</dt><dd>${num(res.dz, 4)} m over ${num(res.sim_time_s)} s</dd>
        <dt>stopped</dt><dd>${esc(res.stop_reason)}: ${esc(res.stop_note || '')}</dd>
        ${res.conclusive ? '' : `<dt>inconclusive</dt><dd>${esc(res.inconclusive_reason)}</dd>`}
        <dt>trend</dt><dd id="trend">${res.trend_p == null ? `not tested: ${esc(res.trend_note || 'a result of an older analysis')}`
          : `period rate changes by ${num(res.trend_slope, 2)} ± ${num(res.trend_slope_se, 2)} m/s² (p = ${num(res.trend_p, 2)})${res.trending ? ' · <b>trending</b>: U_z is the window\'s mean of a drifting rate' : ''}`}</dd>
        <dt>at f</dt><dd id="osc">z oscillates ${num(res.z_osc_amplitude, 3)} m, x ${res.x_osc_amplitude == null ? 'not measured' : `${num(res.x_osc_amplitude, 3)} m`}</dd>
        <dt>engine</dt><dd>${esc(res.engine_version)} · ${res.ranks} rank(s) · ${esc(res.launcher)} · ${num(res.wall_s)} s wall</dd></dl></section>` : ''}
      ${(run.snapshots_taken || []).length ? `<section class="card"><h2>The bed</h2><div class="grid2">${run.snapshots_taken.map(s =>
        `<figure><img class="figure" loading="lazy" src="${esc(authed(s.links.slice_svg))}" alt="slice"><figcaption>t = ${num(s.t_s)} s · <a href="${esc(authed(s.links.vtk))}">VTK</a> · <a href="${esc(authed(s.links.dump))}">dump</a></figcaption></figure>`).join('')}</div></section>` : ''}
      <section class="card"><h2>Log tail</h2><pre id="log-tail">${esc(run.log_tail || '(none yet)')}</pre></section>
      <section class="card"><details><summary>The deck</summary><pre id="deck">${esc(run.deck)}</pre></details></section>`;
  };
  render();
  let t = [], z = [];
  let plot = null;
  const draw = note => {
    const d = decimate(t, z, 2000);
    if (!plot) { if (d.t.length) plot = trajectoriesPlot($('#zt-plot'), [Object.assign(d, { label: `run ${id}` })], { title: '' }); }
    else plot.setData([d.t, d.z]);
    $('#zt-note').textContent = note;
  };
  const showProgress = (simTime, total) => {
    $('#sim-time').textContent = `${num(simTime)} of ${num(total)} s simulated`;
    $('#sim-bar').style.width = `${Math.min(100, 100 * simTime / (total || 1))}%`;
  };
  if (run.trajectory && run.trajectory.t.length) {
    ({ t, z } = run.trajectory);
    draw('The stored trajectory (every dump frame).');
    showProgress(run.result ? run.result.sim_time_s : run.progress.sim_time_s, run.run_duration_s);
  } else {
    showProgress(run.progress.sim_time_s, run.run_duration_s);
    if (run.state === 'running') {
      const trail = await get(`/api/v1/runs/${id}/trail`);
      if (!current(generation)) return;
      t = trail.t.slice(); z = trail.z.slice();
      draw('Live: one point per heartbeat; the whole trajectory replaces it when the run ends.');
    } else {
      $('#zt-note').textContent = run.state === 'queued' ? 'Queued: z(t) appears when it runs.' : 'No trajectory.';
    }
  }
  let wasRunning = run.state === 'running';
  onLive(async snap => {
    const me = (snap.running || []).find(r => r.id === id);
    if (me) {
      wasRunning = true;
      $('#run-state').innerHTML = stateBadge('running');
      showProgress(me.progress.sim_time_s, me.run_duration_s);
      if (me.progress.sim_time_s > (t.length ? t[t.length - 1] : -1)) {
        t.push(me.progress.sim_time_s); z.push(me.progress.so_z);
        draw('Live: one point per heartbeat; the whole trajectory replaces it when the run ends.');
      }
    } else if (wasRunning) {
      const fresh = await get(`/api/v1/runs/${id}`).catch(() => null);
      if (!fresh || !current(generation) || !wasRunning) return;  // a later snapshot tries again
      wasRunning = false;
      run = fresh;
      if (plot) { nav.plots = nav.plots.filter(q => q !== plot); plot.destroy(); }
      plot = null;
      render();
      if (run.trajectory && run.trajectory.t.length) { ({ t, z } = run.trajectory); draw('The stored trajectory (every dump frame).'); }
      showProgress(run.result ? run.result.sim_time_s : run.progress.sim_time_s, run.run_duration_s);
    }
  });
}

async function bedsPage() {
  document.title = 'beds · sandswim';
  const { beds } = await get('/api/v1/beds');
  main().innerHTML = '<h1>Beds</h1><section class="card"><div id="beds"></div></section>';
  dataTable($('#beds'), bedColumns(), beds, { rowId: b => b.id });
}
function bedColumns() {
  return [
    { key: 'id', label: 'id', num: true, html: b => `<a href="/beds/${b.id}">${b.id}</a>` },
    { key: 'scale', label: 'scale' }, { key: 'replicate', label: 'replicate', num: true },
    { key: 'state', label: 'state', html: b => stateBadge(b.state) },
    { key: 'grains', label: 'grains', num: true, value: b => b.result && b.result.grains },
    { key: 'packing', label: 'packing fraction', num: true, value: b => b.result && b.result.packing_fraction, html: b => num(b.result && b.result.packing_fraction) },
    { key: 'bed_height', label: 'height (m)', num: true, value: b => b.result && b.result.bed_height, html: b => num(b.result && b.result.bed_height) },
    { key: 'so_depth', label: 'SO depth (m)', num: true, value: b => b.result && b.result.so_depth, html: b => num(b.result && b.result.so_depth) },
    { key: 'seeds', label: 'seeds', value: b => (b.seeds ? `${b.seeds.pour1} ${b.seeds.pour2}` : ''), html: b => esc(b.seeds ? `${b.seeds.pour1}, ${b.seeds.pour2}` : '') },
    { key: 'runs', label: 'runs', num: true },
  ];
}
async function bedPage(id) {
  document.title = `bed ${id} · sandswim`;
  const b = await get(`/api/v1/beds/${id}`);
  const r = b.result || {};
  main().innerHTML = `<h1>Bed ${id} ${stateBadge(b.state)}</h1><section class="card"><dl class="facts" id="bed">
    <dt>scale</dt><dd>${esc(b.scale)}, replicate ${b.replicate}</dd>
    <dt>seeds</dt><dd>${esc(b.seeds ? `pour ${b.seeds.pour1}, ${b.seeds.pour2}` : 'from before replicates')}</dd>
    <dt>grains</dt><dd>${esc(r.grains ?? '')}</dd>
    <dt>height</dt><dd>${num(r.bed_height)} m</dd>
    <dt>SO depth</dt><dd>${num(r.so_depth)} m</dd>
    <dt>packing fraction</dt><dd>${num(r.packing_fraction)} (in the shell around the SO)</dd>
    <dt>runs on it</dt><dd>${b.runs}</dd>
    ${b.last_error ? `<dt>failure</dt><dd class="error">${esc(JSON.stringify(b.last_error))}</dd>` : ''}
    <dt>key</dt><dd><code>${esc(b.key)}</code></dd></dl></section>`;
}

// ---- Submit: a JSON editor that shows the daemon's field errors next to the field --------------

const exampleSweep = {
  name: 'omega-sign', scale: 'smoke',
  base: { mode: 'oscillatory', A: 0.03, f: 3, Omega: -80, duration_s: 1.5 },
  axes: [{ param: 'Omega', values: [-80, 80] }],
};

// Where each JSON path's value starts in `text` ("axes[0].values[1]" -> offset), by a tolerant scan.
function jsonPathOffsets(text) {
  const out = new Map();
  let i = 0;
  const ws = () => { while (i < text.length && /\s/.test(text[i])) i++; };
  const str = () => { const s = i; i++; while (i < text.length && text[i] !== '"') { if (text[i] === '\\') i++; i++; } i++; try { return JSON.parse(text.slice(s, i)); } catch (e) { return text.slice(s + 1, i - 1); } };
  function value(path) {
    ws();
    out.set(path, i);
    if (text[i] === '{') {
      i++; ws();
      while (i < text.length && text[i] !== '}') {
        ws();
        if (text[i] !== '"') return;  // not JSON here: stop (the map so far is still useful)
        const keyAt = i, key = str();
        const child = path ? `${path}.${key}` : key;
        out.set(child, keyAt);
        ws(); if (text[i] === ':') i++;
        const before = i;
        value(child); out.set(child, keyAt);
        ws(); if (text[i] === ',') i++; ws();
        if (i === before) return;
      }
      i++;
    } else if (text[i] === '[') {
      i++; ws();
      for (let k = 0; i < text.length && text[i] !== ']'; k++) {
        const before = i;
        value(`${path}[${k}]`);
        ws(); if (text[i] === ',') i++; ws();
        if (i === before) return;  // a stray '}' or ':' inside an array: no progress, stop
      }
      i++;
    } else if (text[i] === '"') {
      str();
    } else {
      while (i < text.length && !/[,\]}\s]/.test(text[i])) i++;
    }
  }
  try { value(''); } catch (e) { /* a partial map is still useful */ }
  return out;
}
// The line of `field` in `text`: of its deepest prefix the text holds. The daemon names a sweep's
// fields in the request it made of it ("sweeps[0].base.A" for the sweep sent alone), so a field
// whose "sweeps[0]." the text has not is also read without it; the reading that reaches deeper wins.
function fieldLine(text, field) {
  const offsets = jsonPathOffsets(text);
  const deepest = path => {
    while (path) {
      if (offsets.has(path)) return { depth: path.length, offset: offsets.get(path) };
      const cut = Math.max(path.lastIndexOf('.'), path.lastIndexOf('['));
      path = cut > 0 ? path.slice(0, cut) : '';
    }
    return { depth: 0, offset: 0 };
  };
  const whole = deepest(field), bare = deepest(field.replace(/^sweeps\[0\]\.?/, ''));
  const best = bare.depth > whole.depth ? bare : whole;
  return best.depth ? text.slice(0, best.offset).split('\n').length : 1;
}

// A JSON text editor with line numbers that shows a refusal's field beside its line (the /submit
// page's and the campaign editor's). `draftKey`: the tab keeps the text being typed under it.
// Returns {text(), setText(t), clear(), refused(err)}: refused() shows an ApiError's problem (its
// `field` beside the field's line, its detail under the editor) and returns the line (0: none).
function jsonEditor(container, { initial, draftKey = null, id = 'json-text' }) {
  container.innerHTML = `<div class="editor"><div class="gutter"></div><textarea id="${esc(id)}" spellcheck="false"></textarea></div>
    <div class="editor-errors"></div>`;
  const area = $('textarea', container), gutter = $('.gutter', container), box = $('.editor', container), errors = $('.editor-errors', container);
  area.value = (draftKey && sessionStorage.getItem(draftKey)) || initial;
  let badLine = 0;
  const paint = () => {
    const n = area.value.split('\n').length;
    gutter.innerHTML = Array.from({ length: n }, (_, k) => (k + 1 === badLine ? `<span class="bad">${k + 1}</span>` : String(k + 1))).join('\n');
    gutter.scrollTop = area.scrollTop;
    const marker = $('.field-error', box);
    if (marker) marker.style.top = `${6 + (badLine - 1) * 18 - area.scrollTop}px`;
  };
  const clear = () => {
    for (const m of box.querySelectorAll('.field-error')) m.remove();
    errors.innerHTML = '';
    badLine = 0;
    paint();
  };
  area.addEventListener('input', () => { if (draftKey) sessionStorage.setItem(draftKey, area.value); paint(); });
  area.addEventListener('scroll', paint);
  paint();
  return {
    text: () => area.value,
    setText(t) { area.value = t; if (draftKey) sessionStorage.setItem(draftKey, t); clear(); },
    forget() { if (draftKey) sessionStorage.removeItem(draftKey); },
    clear,
    refused(e) {
      clear();
      const p = e.problem || {};
      const field = p.field || '';
      badLine = field ? fieldLine(area.value, field) : 0;
      const reason = p.detail || e.message;
      errors.innerHTML = `<p class="error">Refused (${esc(e.status || 'network')}): ${esc(reason)}</p>`;
      if (e.status === 401) errors.insertAdjacentHTML('beforeend', '<p>Paste the daemon\'s token in the token box above.</p>');
      if (field) {
        box.insertAdjacentHTML('beforeend', `<div class="field-error" data-field="${esc(field)}" data-line="${badLine}">line ${badLine} · ${esc(field)}: ${esc(reason.replace(`${field}: `, ''))}</div>`);
      }
      paint();
      return badLine;
    },
  };
}

async function submitPage() {
  document.title = 'submit · sandswim';
  main().innerHTML = `<h1>Submit a sweep</h1>
    <p class="muted">A sweep (or <code>{"campaign": "paper-58"}</code>) as the REST API takes it: see <a href="/api-reference">the REST API</a> and <a href="/help/docs/how-to/sweeps.md">how to write a sweep</a>. The daemon checks every field; an error is shown next to its field, and nothing is stored.
    A study to rerun, edit and schedule is a <a href="/campaigns">campaign</a>.</p>
    <div id="sweep-editor"></div>
    <p><button id="submit">Submit</button> <span id="submit-result"></span></p>`;
  const editor = jsonEditor($('#sweep-editor'), { initial: JSON.stringify(exampleSweep, null, 2), draftKey: 'sandswim-draft', id: 'sweep-json' });
  $('#submit').addEventListener('click', async () => {
    editor.clear();
    $('#submit-result').textContent = 'submitting…';
    try {
      const { body, res } = await post('/api/v1/sweeps', editor.text());
      $('#submit-result').textContent = '';
      say(`Submitted: ${body.runs} runs (${body.runs_new} new, ${body.runs_reused} reused).`, true);
      const location = (res.headers.get('Location') || '').replace('/api/v1', '');
      history.pushState(null, '', location || '/');
      route();
    } catch (e) {
      $('#submit-result').textContent = '';
      editor.refused(e);
    }
  });
}

// ---- Campaigns: the catalogue, one campaign, its editor --------------------------------------------

const scales = ['smoke', 'mini', 'paper'];
const scaleSelect = (id, chosen = 'smoke') => `<select id="${esc(id)}">${scales.map(s => `<option${s === chosen ? ' selected' : ''}>${s}</option>`).join('')}</select>`;
const campaignPath = name => `/api/v1/campaigns/${encodeURIComponent(name)}`;
const send = (method, path, body) => api(path, Object.assign({ method },
  body === undefined ? {} : { headers: { 'Content-Type': 'application/json' }, body: typeof body === 'string' ? body : JSON.stringify(body) }));
const scheduleText = s => (s ? `${s.cron} at ${s.scale || 'its scale'}${s.next_due ? `, next ${when(s.next_due)}` : ''}` +
  `${s.source === 'flag' ? ' (sandswimd --schedule)' : ''}` : '');
// A built-in campaign's description tells to edit it "in your own copy": that phrase opens the
// editor with the copy (the "Make my own copy" of its page).
function describe(c) {
  const text = esc(c.description || '');
  if (!c.builtin) return text;
  return text.replace('your own copy of this campaign',
    `<a class="own-copy" href="/new-campaign?from=${encodeURIComponent(c.name)}">your own copy of this campaign</a>`);
}

async function campaignsPage() {
  document.title = 'campaigns · sandswim';
  const generation = nav.generation;
  const { campaigns } = await get('/api/v1/campaigns');
  if (!current(generation)) return;
  main().innerHTML = `<h1>Campaigns</h1>
    <p class="muted">A campaign is a study to rerun: its sweeps, claims, precision, replicate beds, snapshots and drift tolerance.
    Built-in campaigns are read-only: open one and make your own copy, or <a href="/new-campaign">write a new campaign</a>.</p>
    <section class="card"><div id="campaign-list"></div></section>`;
  if (!campaigns.length) {
    $('#campaign-list').innerHTML = '<p>No campaigns on this daemon. <a href="/new-campaign">Write one</a>.</p>';
    return;
  }
  const rows = campaigns.map(c => Object.assign({}, c, { last: null }));
  const table = dataTable($('#campaign-list'), [
    { key: 'name', label: 'name', html: c => `<a href="/campaigns/${encodeURIComponent(c.name)}">${esc(c.name)}</a>` },
    { key: 'version', label: 'version', num: true, html: c => (c.builtin ? '<span class="muted">built-in</span>' : esc(c.version)) },
    { key: 'builtin', label: 'built-in', value: c => (c.builtin ? 'built-in' : 'own'), html: c => (c.builtin ? 'yes (read-only)' : 'no') },
    { key: 'extends', label: 'extends', html: c => (c.extends ? `<a href="/campaigns/${encodeURIComponent(c.extends)}">${esc(c.extends)}</a>` : '') },
    { key: 'scale', label: 'scale' },
    { key: 'schedule', label: 'schedule', value: c => scheduleText(c.schedule),
      html: c => esc(scheduleText(c.schedule) || 'none') + (!c.schedule && c.definition_schedule ? ` <span class="muted">(its definition suggests ${esc(c.definition_schedule)})</span>` : '') },
    { key: 'last', label: 'last run', value: c => (c.last ? c.last.created_at : null),
      html: c => (c.last === null ? '<span class="muted">…</span>' : c.last ? `<a href="/campaign-runs/${c.last.id}">${c.last.id}</a> ${esc(when(c.last.created_at))} (${esc(c.last.scale)})` : '<span class="muted">never run</span>') },
  ], rows, { filterPlaceholder: 'filter campaigns', rowId: c => c.name });
  // The last run of each: one small read per campaign (a catalogue holds a few).
  await Promise.all(rows.map(async c => {
    const r = await get(`/api/v1/campaign-runs?campaign=${encodeURIComponent(c.name)}&limit=1`).catch(() => ({ campaign_runs: [] }));
    c.last = (r.campaign_runs || [])[0] || false;
  }));
  if (current(generation)) table.render();
}

async function campaignPage(name) {
  document.title = `${name} · campaigns · sandswim`;
  const generation = nav.generation;
  const version = new URLSearchParams(location.search).get('version');
  const c = await get(`${campaignPath(name)}${version ? `?version=${encodeURIComponent(version)}` : ''}`);
  if (!current(generation)) return;
  const newest = c.current_version ?? Math.max(c.version, ...(c.versions || []).map(v => v.version));
  const plan = c.planned_runs || {};
  main().innerHTML = `<h1>Campaign ${esc(c.name)} <span class="muted">${c.builtin ? 'built-in (read-only)' : `version ${esc(c.version)}`}</span></h1>
    ${!c.builtin && c.version < newest ? `<p class="action-message">This is version ${esc(c.version)}; the current one is version ${newest}: <a href="/campaigns/${encodeURIComponent(name)}">see it</a>.</p>` : ''}
    <section class="card"><dl class="facts">
      <dt>about</dt><dd class="wrap">${describe(Object.assign({}, c.resolved, { name: c.name, builtin: c.builtin })) || '<span class="muted">no description</span>'}</dd>
      ${c.extends ? `<dt>extends</dt><dd><a href="/campaigns/${encodeURIComponent(c.extends)}">${esc(c.extends)}</a> ${c.extends_version ? `version ${esc(c.extends_version)}` : '(built-in)'}, as it was when this version was saved</dd>` : ''}
      <dt>scale</dt><dd>${esc((c.resolved || {}).scale || '')}</dd>
      <dt>plans</dt><dd id="planned">${scales.filter(s => plan[s] !== undefined).map(s => `${esc(plan[s])} runs at ${s}`).join(' · ') || '<span class="muted">unknown</span>'}</dd>
      ${(c.notes || []).length ? `<dt>notes</dt><dd class="wrap"><ul id="notes">${c.notes.map(n => `<li>${esc(n)}</li>`).join('')}</ul></dd>` : ''}
      <dt></dt><dd id="campaign-actions">${c.builtin
        ? `<a class="button" id="make-copy" href="/new-campaign?from=${encodeURIComponent(name)}">Make my own copy</a>`
        : `<a class="button" id="edit" href="/campaigns/${encodeURIComponent(name)}/edit">Edit</a>`}
        · Run now at ${scaleSelect('run-scale', (c.resolved || {}).scale === 'paper' ? 'smoke' : (c.resolved || {}).scale)} <button id="run-now">Run now</button>
        ${c.builtin ? '' : ' · <button id="delete" class="danger">Delete</button>'}</dd>
    </dl></section>
    <section class="card"><h2>Schedule</h2><p id="schedule-now">${c.schedule ? `Runs at <code>${esc(c.schedule.cron)}</code> (cron, in the daemon's local time) at ${esc(c.schedule.scale)}${c.schedule.next_due ? `; next ${esc(when(c.schedule.next_due))}` : ''}${c.schedule.source === 'flag' ? ' (set by sandswimd --schedule when it started)' : ''}.` : 'Not scheduled: set a cron line (minute hour day-of-month month day-of-week) to rerun it.'}</p>
      <p><label>cron <input id="cron" value="${esc(c.schedule ? c.schedule.cron : (c.resolved || {}).schedule || '0 2 * * *')}" size="16"></label>
        <label>scale ${scaleSelect('schedule-scale', c.schedule ? c.schedule.scale : 'smoke')}</label>
        <button id="schedule-set">${c.schedule ? 'Change the schedule' : 'Schedule'}</button>
        ${c.schedule ? '<button id="schedule-remove" class="danger">Remove the schedule</button>' : ''}
        <span id="schedule-error" class="error"></span></p></section>
    <section class="card"><h2>Runs of this campaign</h2><div id="campaign-runs-of"></div></section>
    ${c.builtin ? '' : '<section class="card"><h2>Versions</h2><div id="versions"></div></section>'}
    <section class="card"><h2>Definition${c.builtin ? '' : ` (version ${esc(c.version)}, as written)`}</h2><pre id="definition">${esc(JSON.stringify(c.definition, null, 2))}</pre>
      ${c.extends ? `<details><summary>What runs (resolved against ${esc(c.extends)})</summary><pre id="resolved">${esc(JSON.stringify(c.resolved, null, 2))}</pre></details>` : ''}</section>`;
  const runs = c.runs || [];
  if (runs.length) {
    dataTable($('#campaign-runs-of'), [
      { key: 'id', label: 'campaign run', num: true, html: r => `<a href="/campaign-runs/${r.id}">${r.id}</a>` },
      { key: 'campaign_version', label: 'version', num: true, html: r => (r.campaign_version ? esc(r.campaign_version) : 'built-in') },
      { key: 'scale', label: 'scale' },
      { key: 'trigger', label: 'trigger' },
      { key: 'status', label: 'state', html: r => stateBadge(r.status) },
      { key: 'progress', label: 'progress', value: r => (r.counts ? r.counts.done : null), html: r => (r.counts ? progressHtml(r.counts, null) : '') },
      { key: 'created_at', label: 'started', html: r => esc(when(r.created_at)) },
    ], runs.slice().sort((a, b) => b.id - a.id), { filterPlaceholder: 'filter runs', rowId: r => r.id });
  } else {
    $('#campaign-runs-of').innerHTML = '<p class="muted">Not run yet: “Run now” above, or schedule it.</p>';
  }
  if (!c.builtin) {
    dataTable($('#versions'), [
      { key: 'version', label: 'version', num: true, html: v => `<a href="/campaigns/${encodeURIComponent(name)}?version=${v.version}">${v.version}</a>${v.version === c.version ? ' (shown)' : ''}` },
      { key: 'created_at', label: 'saved', html: v => esc(when(v.created_at)) },
      { key: 'extends', label: 'extends', value: v => (v.extends ? `${v.extends} ${v.extends_version || 'built-in'}` : ''),
        html: v => (v.extends ? `${esc(v.extends)} ${v.extends_version ? `version ${esc(v.extends_version)}` : '(built-in)'}` : '') },
      { key: 'definition_sha256', label: 'definition (SHA-256)', html: v => `<code title="${esc(v.definition_sha256)}">${esc((v.definition_sha256 || '').slice(0, 12))}</code>` },
    ], (c.versions || []).slice().sort((a, b) => b.version - a.version), { filterPlaceholder: 'filter versions', rowId: v => v.version });
  }
  $('#run-now').addEventListener('click', async () => {
    const scale = $('#run-scale').value;
    try {
      const { body } = await post(`${campaignPath(name)}/runs`, { scale });
      say(`Campaign ${name} submitted at ${scale}: campaign run ${body.id} (${body.runs} runs, ${body.runs_new} new).`, true);
      history.pushState(null, '', `/campaign-runs/${body.id}`);
      route();
    } catch (e) { say(refusal(e)); }
  });
  const del = $('#delete');
  if (del) {
    del.addEventListener('click', async () => {
      if (!del.dataset.armed) {  // two clicks: a dialog box would stop the page's scripts
        del.dataset.armed = '1';
        del.textContent = `Really delete ${name}? (its past runs stay readable)`;
        return;
      }
      try {
        await send('DELETE', campaignPath(name));
        say(`Campaign ${name} deleted; its past campaign runs stay readable.`, true);
        history.pushState(null, '', '/campaigns');
        route();
      } catch (e) { say(refusal(e)); delete del.dataset.armed; del.textContent = 'Delete'; }
    });
  }
  $('#schedule-set').addEventListener('click', async () => {
    $('#schedule-error').textContent = '';
    try {
      const { body } = await send('PUT', `${campaignPath(name)}/schedule`, { cron: $('#cron').value.trim(), scale: $('#schedule-scale').value });
      say(`Campaign ${name} scheduled: ${scheduleText(body)}.`, true);
      route();
    } catch (e) {
      $('#schedule-error').textContent = `Refused (${e.status || 'network'}): ${e.message}`;
      if ((e.problem || {}).field === 'cron') $('#cron').classList.add('bad-input');
      if (e.status === 401) say(refusal(e));
    }
  });
  const remove = $('#schedule-remove');
  if (remove) {
    remove.addEventListener('click', async () => {
      try {
        await send('DELETE', `${campaignPath(name)}/schedule`);
        say(`Campaign ${name} is no longer scheduled.`, true);
        route();
      } catch (e) { say(refusal(e)); }
    });
  }
}

// The campaign editor: a new campaign (/new-campaign, ?from=BASE for a copy of BASE) or a new
// version of one (/campaigns/NAME/edit). Saved with PUT; a refusal's field is shown beside its
// line and nothing is stored.
async function campaignEditorPage(name, from) {
  document.title = `${name ? `edit ${name}` : 'new campaign'} · sandswim`;
  const generation = nav.generation;
  let initial, base = null, heading;
  if (name) {
    const c = await get(campaignPath(name)).catch(e => { if (e.status === 404) return null; throw e; });
    if (!current(generation)) return;
    if (c && c.builtin) {
      main().innerHTML = `<h1>${esc(name)} is built-in</h1><p>A built-in campaign is read-only. <a id="make-copy" class="button" href="/new-campaign?from=${encodeURIComponent(name)}">Make my own copy</a> and edit that.</p>`;
      return;
    }
    initial = c ? JSON.stringify(c.definition, null, 2) : JSON.stringify({ name, extends: 'paper-58' }, null, 2);
    heading = c ? `Edit campaign ${esc(name)} <span class="muted">(version ${esc(c.version)}; saving makes version ${esc(c.version + 1)})</span>` : `New campaign ${esc(name)}`;
    if (c && c.extends) from = c.extends;
  } else {
    initial = JSON.stringify(from ? { name: `my-${from}`, extends: from } : { name: 'my-campaign', extends: 'paper-58' }, null, 2);
    heading = from ? `My own copy of ${esc(from)}` : 'New campaign';
  }
  if (from) base = await get(campaignPath(from)).catch(() => null);
  if (!current(generation)) return;
  const baseSweeps = base ? ((base.resolved || {}).sweeps || []).map(s => s.name) : [];
  const baseClaims = base ? ((base.resolved || {}).claims || []).map(c => c.id) : [];
  main().innerHTML = `<h1>${heading}</h1>
    <p class="muted">The campaign as JSON (<a href="/help/docs/how-to/campaigns.md">how to write a campaign</a>; <a href="/api-reference/campaigns">the REST API</a>; schema/campaign.schema.json). The daemon checks every field when you save;
    an error is shown beside its line and nothing is stored. Each save of a change makes a new version; its past runs keep the definition they ran.</p>
    <div id="campaign-editor"></div>
    <p><button id="save">Save</button> <span id="save-result"></span></p>
    ${base ? `<section class="card" id="base-help"><h2>Starting from ${esc(from)}</h2>
      <p>With <code>"extends": ${esc(JSON.stringify(from))}</code> every field you leave out is ${esc(from)}'s (as it is when you save); every field you write replaces its.
      To keep only some of its sweeps, list them by name (an object in the list is a sweep of your own); its claims that name only the sweeps you keep stay, and you may list your own.</p>
      <p>Its sweeps: <code id="base-sweeps">${esc(JSON.stringify(baseSweeps))}</code></p>
      <p>Its claims: <code>${esc(JSON.stringify(baseClaims))}</code> · e.g. <code>"replicates": 3</code> runs each point on three beds.</p></section>` : ''}`;
  const draftKey = `sandswim-campaign-draft:${name || `new:${from || ''}`}`;
  const editor = jsonEditor($('#campaign-editor'), { initial, draftKey, id: 'campaign-json' });
  $('#save').addEventListener('click', async () => {
    editor.clear();
    const text = editor.text();
    // The name the text gives (the path's when it gives none); text that is not JSON goes to the
    // daemon as it is, so that its reason says where.
    let target = name;
    try { const d = JSON.parse(text); if (d && typeof d.name === 'string') target = d.name; } catch (err) {
      const m = text.match(/"name"\s*:\s*"([^"\\]*)"/);
      if (m) target = m[1];
    }
    if (!target) {
      editor.refused({ status: 'not sent', problem: { field: 'name', detail: 'name: give the campaign a "name" (1 to 64 of A-Z a-z 0-9 . _ -): it is stored under it' } });
      return;
    }
    $('#save-result').textContent = 'saving…';
    try {
      const { body, res } = await send('PUT', campaignPath(target), text);
      $('#save-result').textContent = '';
      editor.forget();
      const plan = body.planned_runs || {};
      say(`${res.status === 201 ? 'Created' : 'Saved'} campaign ${body.name}, version ${body.version}${body.unchanged ? ' (unchanged: the same as the current version)' : ''}; ` +
        `it plans ${scales.filter(s => plan[s] !== undefined).map(s => `${plan[s]} runs at ${s}`).join(', ') || 'an unknown number of runs'}.` +
        `${(body.notes || []).length ? ` Notes: ${body.notes.join(' ')}` : ''}`, true);
      history.pushState(null, '', `/campaigns/${encodeURIComponent(body.name)}`);
      route();
    } catch (e) {
      $('#save-result').textContent = '';
      editor.refused(e);
    }
  });
}

// ---- The REST API, rendered from the daemon's own description (/api/v1/openapi.json) -----------
// The same grouping as docs/reference/api/ (tests/docs/check_docs.py): by the path's first segment
// after /api/v1/, the operations routes (/healthz, /metrics, backup, cost model) together.

function apiResourceOf(path) {
  const m = path.match(/^\/api\/v1\/([^/{]+)/);
  if (!m) return 'operations';
  return ['openapi.json', 'backup', 'cost-model'].includes(m[1]) ? 'operations' : m[1];
}
// A description's text, its `code` spans shown as code.
const apiText = t => esc(t || '').replace(/`([^`]+)`/g, '<code>$1</code>');
function apiSchemaText(s) {
  if (!s || typeof s !== 'object') return '';
  if (s.$ref) {
    const name = s.$ref.split('/').pop();
    return `<a href="/api-reference/schemas#schema-${esc(name)}">${esc(name)}</a>`;
  }
  for (const k of ['oneOf', 'anyOf', 'allOf']) if (s[k]) return s[k].map(apiSchemaText).join(k === 'allOf' ? ' and ' : ' or ');
  if (s.type === 'array') return `array of ${apiSchemaText(s.items) || 'values'}`;
  if (s.enum) return `${esc(s.type || '')} (${s.enum.map(v => `<code>${esc(v)}</code>`).join(', ')})`;
  return esc(s.type || '');
}
async function apiReferencePage(resource) {
  const doc = await get('/api/v1/openapi.json');
  const groups = {};
  for (const [path, ops] of Object.entries(doc.paths || {})) {
    for (const [method, op] of Object.entries(ops)) {
      if (typeof op !== 'object' || method === 'parameters') continue;
      (groups[apiResourceOf(path)] ||= []).push({ method, path, op });
    }
  }
  const nav = `<p><a href="/api-reference">All resources</a> · <a href="/api-reference/schemas">Schemas</a> · ` +
    `<a href="/api/v1/openapi.json">the description as JSON</a></p>`;
  if (!resource) {
    main().innerHTML = `<h1>REST API</h1>${nav}<p>${apiText(doc.info?.description)}</p>
      <table><thead><tr><th>resource</th><th>routes</th></tr></thead><tbody>${Object.keys(groups).sort().map(r =>
        `<tr><td><a href="/api-reference/${esc(r)}">${esc(r)}</a></td><td>${groups[r].map(o =>
          `<code>${esc(o.method.toUpperCase())} ${esc(o.path)}</code>`).join('<br>')}</td></tr>`).join('')}</tbody></table>`;
    return;
  }
  if (resource === 'schemas') {
    main().innerHTML = `<h1>REST API: schemas</h1>${nav}` + Object.entries(doc.components?.schemas || {}).map(([name, s]) => {
      const req = new Set(s.required || []);
      const props = Object.entries(s.properties || {});
      return `<section class="card" id="schema-${esc(name)}"><h2>${esc(name)}</h2><p>${apiText(s.description)}</p>` +
        (props.length ? `<table><thead><tr><th>field</th><th>type</th><th>unit</th><th>required</th><th>what</th></tr></thead><tbody>${
          props.map(([k, v]) => `<tr><td><code>${esc(k)}</code></td><td>${apiSchemaText(v)}</td><td>${esc(v['x-unit'] || '')}</td>` +
            `<td>${req.has(k) ? 'yes' : 'no'}</td><td>${apiText(v.description)}</td></tr>`).join('')}</tbody></table>`
          : `<p>Type: ${apiSchemaText(s)}</p>`) + '</section>';
    }).join('');
    if (location.hash) document.getElementById(location.hash.slice(1))?.scrollIntoView();
    return;
  }
  const ops = groups[resource];
  if (!ops) throw new ApiError(404, { detail: `no resource ${resource} in the API` });
  main().innerHTML = `<h1>REST API: ${esc(resource)}</h1>${nav}` + ops.map(({ method, path, op }) => {
    const params = op.parameters || [];
    return `<section class="card"><h2><code>${esc(method.toUpperCase())} ${esc(path)}</code></h2>
      <p>${apiText(op.summary)}</p><p class="muted">${apiText(op.description)}</p>` +
      (params.length ? `<table><thead><tr><th>parameter</th><th>in</th><th>required</th><th>type</th><th>what</th></tr></thead><tbody>${
        params.map(p => `<tr><td><code>${esc(p.name)}</code></td><td>${esc(p.in)}</td><td>${p.required ? 'yes' : 'no'}</td>` +
          `<td>${apiSchemaText(p.schema)}</td><td>${apiText(p.description)}</td></tr>`).join('')}</tbody></table>` : '') +
      Object.entries(op.requestBody?.content || {}).map(([ct, c]) =>
        `<p>Request body (<code>${esc(ct)}</code>): ${apiSchemaText(c.schema)}</p>`).join('') +
      `<table><thead><tr><th>status</th><th>what</th><th>body</th></tr></thead><tbody>${
        Object.entries(op.responses || {}).map(([code, r]) => `<tr><td>${esc(code)}</td><td>${apiText(r.description)}</td><td>${
          Object.entries(r.content || {}).map(([ct, c]) => `<code>${esc(ct)}</code> ${apiSchemaText(c.schema)}`).join(', ')}</td></tr>`).join('')
      }</tbody></table></section>`;
  }).join('');
}

// ---- Help: the docs compiled into the daemon (docs/**/*.md), rendered here ---------------------
// A small Markdown reader for the docs' own subset: headings, paragraphs, lists, tables, code
// blocks (fenced and indented), links, images, `code`, **bold** and *italics*. A link to another
// docs page stays in the dashboard (/help/docs/...); one out of docs/ is shown as its path.

function helpResolve(base, target) {
  const parts = base.split('/').slice(0, -1);
  for (const p of target.split('/')) {
    if (p === '..') parts.pop();
    else if (p !== '.' && p !== '') parts.push(p);
  }
  return parts.join('/');
}
function helpAnchor(text) {
  return text.replace(/`|\*\*|\*|\[|\]\([^)]*\)/g, '').trim().toLowerCase().replace(/[^\p{L}\p{N}_\- ]/gu, '').replace(/ /g, '-');
}
function helpInline(text, base) {
  const codes = [];
  let t = esc(text).replace(/`([^`]+)`/g, (_, c) => { codes.push(c); return `\u0000${codes.length - 1}\u0000`; });
  t = t.replace(/!\[([^\]]*)\]\(([^)\s]+)[^)]*\)/g, (_, alt) => `<em>[${alt}]</em>`);
  t = t.replace(/\[([^\]]+)\]\(([^)\s]+)\)/g, (_, label, target) => {
    const href = target.replace(/&amp;/g, '&');
    if (/^[a-z]+:/.test(href)) return `<a href="${esc(href)}" rel="noopener">${label}</a>`;
    const [path, anchor] = href.split('#');
    const resolved = path ? helpResolve(base, path) : base;
    if (resolved.startsWith('docs/') && resolved.endsWith('.md')) {
      return `<a href="/help/${esc(resolved)}${anchor ? '#' + esc(anchor) : ''}">${label}</a>`;
    }
    return `${label} (<code>${esc(resolved)}</code>)`;
  });
  t = t.replace(/\*\*([^*]+)\*\*/g, '<strong>$1</strong>').replace(/(^|[\s(])\*([^*\s][^*]*)\*/g, '$1<em>$2</em>');
  return t.replace(/\u0000(\d+)\u0000/g, (_, i) => `<code>${codes[Number(i)]}</code>`);  // escaped above
}
function helpRender(md, base) {
  const lines = md.split('\n'), out = [], seen = {};
  let i = 0;
  const isBlank = l => !l.trim();
  while (i < lines.length) {
    const line = lines[i];
    if (isBlank(line)) { i++; continue; }
    let m;
    if (line.startsWith('```')) {
      const code = [];
      for (i++; i < lines.length && !lines[i].startsWith('```'); i++) code.push(lines[i]);
      i++;
      out.push(`<pre>${esc(code.join('\n'))}</pre>`);
    } else if (line.startsWith('    ')) {
      const code = [];
      while (i < lines.length && (lines[i].startsWith('    ') || (isBlank(lines[i]) && (lines[i + 1] || '').startsWith('    ')))) code.push(lines[i++].slice(4));
      out.push(`<pre>${esc(code.join('\n'))}</pre>`);
    } else if ((m = line.match(/^(#{1,6})\s+(.*)$/))) {
      let id = helpAnchor(m[2]);
      seen[id] = (seen[id] || 0) + 1;
      if (seen[id] > 1) id += `-${seen[id] - 1}`;
      out.push(`<h${m[1].length} id="${esc(id)}">${helpInline(m[2], base)}</h${m[1].length}>`);
      i++;
    } else if (line.startsWith('|')) {
      const rows = [];
      while (i < lines.length && lines[i].startsWith('|')) rows.push(lines[i++]);
      const cells = r => r.replace(/^\||\|$/g, '').split(/(?<!\\)\|/).map(c => c.trim().replace(/\\\|/g, '|'));
      const body = rows.filter((r, k) => k !== 1 || !/^\|[\s:|-]+\|?$/.test(r));
      out.push(`<table><thead><tr>${cells(body[0]).map(c => `<th>${helpInline(c, base)}</th>`).join('')}</tr></thead><tbody>${
        body.slice(1).map(r => `<tr>${cells(r).map(c => `<td>${helpInline(c.replace(/<br>/g, ' '), base)}</td>`).join('')}</tr>`).join('')}</tbody></table>`);
    } else if (/^\s*([-*]|\d+\.)\s/.test(line)) {
      const ordered = /^\s*\d+\./.test(line), items = [];
      while (i < lines.length && !isBlank(lines[i])) {
        if (/^\s{0,1}([-*]|\d+\.)\s/.test(lines[i])) items.push(lines[i].replace(/^\s*([-*]|\d+\.)\s+/, ''));
        else items[items.length - 1] += ' ' + lines[i].trim();
        i++;
      }
      const tag = ordered ? 'ol' : 'ul';
      out.push(`<${tag}>${items.map(it => `<li>${helpInline(it, base)}</li>`).join('')}</${tag}>`);
    } else {
      const para = [];
      while (i < lines.length && !isBlank(lines[i]) && !/^(#{1,6}\s|```|\|)/.test(lines[i])) para.push(lines[i++]);
      out.push(`<p>${helpInline(para.join(' '), base)}</p>`);
    }
  }
  return out.join('\n');
}
async function helpPage(path) {
  const res = await fetch(`/help-files/${path}`);
  if (!res.ok) throw new ApiError(res.status, { detail: `no docs page ${path}` });
  main().innerHTML = `<p class="muted"><a href="/help/docs/index.md">All docs</a> · ${esc(path)}</p>` +
    `<article class="card help">${helpRender(await res.text(), path)}</article>`;
  if (location.hash) document.getElementById(decodeURIComponent(location.hash.slice(1)))?.scrollIntoView();
}

// ---- Routing ------------------------------------------------------------------------------------

async function route() {
  const path = location.pathname.replace(/\/+$/, '') || '/';
  let m;
  try {
    if (path === '/') await overviewPage();
    else if ((m = path.match(/^\/campaign-runs\/(\d+)$/))) await campaignRunPage(Number(m[1]));
    else if ((m = path.match(/^\/sweeps\/(\d+)$/))) await sweepPage(Number(m[1]));
    else if ((m = path.match(/^\/runs\/(\d+)$/))) await runPage(Number(m[1]));
    else if ((m = path.match(/^\/beds\/(\d+)$/))) await bedPage(Number(m[1]));
    else if (path === '/beds') await bedsPage();
    else if (path === '/submit') await submitPage();
    else if (path === '/campaigns') await campaignsPage();
    else if ((m = path.match(/^\/campaigns\/([A-Za-z0-9._-]{1,64})$/))) await campaignPage(m[1]);
    else if ((m = path.match(/^\/campaigns\/([A-Za-z0-9._-]{1,64})\/edit$/))) await campaignEditorPage(m[1], null);
    else if (path === '/new-campaign') await campaignEditorPage(null, new URLSearchParams(location.search).get('from'));
    else if (path === '/help') await helpPage('docs/index.md');
    else if ((m = path.match(/^\/help\/(docs\/[A-Za-z0-9_./-]{1,200}\.md)$/))) await helpPage(m[1]);
    else if (path === '/api-reference') await apiReferencePage(null);
    else if ((m = path.match(/^\/api-reference\/([a-z-]{1,40})$/))) await apiReferencePage(m[1]);
    else main().innerHTML = `<h1>Not found</h1><p>No page at ${esc(path)}. <a href="/">The overview</a>.</p>`;
  } catch (e) {
    main().innerHTML = `<h1>Cannot show this page</h1><p class="error">${esc(e.message)}</p>` +
      (e.status === 401 ? '<p class="needs-token">This daemon needs its token: open the link sandswimd printed when it started (…/?token=…), or paste the token (the file <code>token</code> in its --data directory) in the token box above.</p>' : '') +
      (e.status === 404 ? `<p>It does not exist on this daemon. ${path.startsWith('/campaigns') ? '<a href="/campaigns">The campaigns</a> · ' : ''}<a href="/">The overview</a>.</p>` : '');
  }
}

function start() {
  const tokenBox = $('#token');
  tokenBox.value = token();
  tokenBox.addEventListener('change', () => {
    sessionStorage.setItem('sandswim-token', tokenBox.value.trim());
    if ($('#main .needs-token')) route();  // a page the token was missing for: show it now
  });
  document.addEventListener('click', e => {
    const a = e.target.closest('a');
    if (!a || a.target || e.ctrlKey || e.metaKey || e.shiftKey || a.origin !== location.origin || a.pathname.startsWith('/api/')) return;
    // A link within the page (a docs page's #anchor) is the browser's to follow.
    if (a.hash && a.pathname === location.pathname && a.search === location.search) return;
    e.preventDefault();
    history.pushState(null, '', a.pathname + a.search + a.hash);
    $('#action-message').hidden = true;
    route();
  });
  window.addEventListener('popstate', () => { leavePage(); route(); });
  const pushState = history.pushState.bind(history);
  history.pushState = (...args) => { leavePage(); pushState(...args); };
  // A page brought back from the browser's back-forward cache has closed its stream: start afresh.
  window.addEventListener('pageshow', e => { if (e.persisted) location.reload(); });
  runLive();
  route();
}
start();
