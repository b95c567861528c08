// The scene view (GET /scenes/{id}/view): reads GET /scenes/{id}/view/state, draws it (scene3d.js), follows the
// scene's server-sent events and reads the state again after a push, an assignment or a finished simulation.
// `window.lumenlink` exposes what the page shows, for people poking in the console and for the browser tests.

import { Viewer, CHANGE_COLOURS } from "./scene3d.js";
import { Scale, drawLegend, formatLux, turbo } from "./colour.js";
import { followEvents, getJSON, postJSON, putJSON } from "./api.js";

const sceneId = document.body.dataset.scene;
const $ = (id) => document.getElementById(id);

/** What the page shows now (read by the tests; nothing here is an API). */
const ll = (window.lumenlink = {
  sceneId, ready: false, revision: null, loads: 0, events: [], connection: "connecting", scale: "linear",
  state: null, lastPick: null, error: null, jobs: [],
  counts: () => viewer?.counts(),                  // meshes in the three.js scene: {instances, sensors}
  screenOf: (p) => viewer?.screenOf(p),            // client coordinates of a world point (m)
  pixelAt: (x, y) => viewer?.pixelAt(x, y),        // RGBA drawn there
  matrixOf: (instance) => viewer?.matrixOf(instance),
  colourOf: (lux) => { const s = new Scale(ll.scale, vmaxOf(ll.state?.sensors ?? [])); return turbo(s.norm(lux)); },
});

let viewer = null;
try {
  viewer = new Viewer($("canvas"));
} catch (err) {   // no WebGL: say so instead of a blank page
  fail(`cannot draw in 3D here: ${err.message}`);
}

// ------------------------------------------------------------------------------------------- state

let loading = null;   // the state read in progress
let again = false;    // another read was asked for while one ran

/** Read the state and draw it; reads asked for meanwhile are folded into one more read. */
async function refresh() {
  if (loading) { again = true; return loading; }
  loading = (async () => {
    do {
      again = false;
      try {
        const state = await getJSON(`/scenes/${sceneId}/view/state`);
        ll.state = state;
        await draw(state);
        ll.revision = state.scene.revision;
        ll.loads += 1;
        ll.ready = true;
        ll.error = null;
        status();
      } catch (err) {
        fail(`could not read the scene: ${err.message}`);
      }
    } while (again);
    loading = null;
  })();
  return loading;
}

/** The top of the shared colour scale: the lux that 99 % of the lit, well-measured AREA stays below, over all
 *  sensor results (grid cells, weighted by their area, and surface triangles, by theirs; well measured: standard
 *  error at most half the value). The plain maximum would let a few small, very bright triangles (the inside of a
 *  headlamp: 10^8 lx at millimetres from its lamp) paint the rest of the model black. Brighter values saturate;
 *  the legend's top label says "≥". Falls back to the maximum where nothing is well measured. */
function vmaxOf(sensors) {
  const good = [];
  let vmax = 0;
  const take = (v, e, a) => { vmax = Math.max(vmax, v); if (v > 0 && a > 0 && e <= 0.5 * v) good.push([v, a]); };
  for (const s of sensors) {
    const lux = s.result?.lux ?? [], err = s.result?.stderr ?? [];
    const cell = s.u && s.v ? Math.hypot(s.u[1] * s.v[2] - s.u[2] * s.v[1], s.u[2] * s.v[0] - s.u[0] * s.v[2],
                                         s.u[0] * s.v[1] - s.u[1] * s.v[0]) / ((s.nu || 1) * (s.nv || 1)) : 1;
    lux.forEach((row, j) => row.forEach((v, i) => take(v, err[j]?.[i] ?? Infinity, cell)));
    for (const part of s.result?.instances ?? []) part.lux.forEach((v, i) => take(v, part.stderr[i], part.area[i]));
  }
  if (!good.length) return vmax;
  good.sort((x, y) => x[0] - y[0]);
  const total = good.reduce((sum, [, a]) => sum + a, 0);
  let below = 0;
  for (const [v, a] of good) {
    below += a;
    if (below >= 0.99 * total) return v;
  }
  return good[good.length - 1][0];
}

async function draw(state) {
  if (!viewer) return;
  await viewer.setInstances(state, $("highlight").checked);
  drawSensors();
  viewer.setLights(state.lights);
  listChanges(state.last_push);
  listJobs(state.jobs);
  listElements(state.elements ?? [], state.nodes ?? []);
}

/** The optical elements with an inside on the scene's parts: which part, which library element, applied or why not. */
function listElements(elements, nodes) {
  const pathOf = new Map(nodes.map((n) => [n.uuid, n.path]));
  if (!elements.length) {
    const li = document.createElement("li");
    li.className = "muted";
    li.textContent = "none";
    $("elements").replaceChildren(li);
    return;
  }
  $("elements").replaceChildren(...elements.map((e) => {
    const li = document.createElement("li");
    const where = pathOf.get(e.body.node) ?? e.body.node;
    const type = elementType(e.body.element);
    li.textContent = `${where}: element ${e.body.element.slice(0, 12)} (${type === "grating" ? "grating" : e.model})` +
      (e.applied ? "" : ` — not applied: ${e.problem ?? "its node is gone"}`);
    if (type === "grating") {
      const plot = document.createElement("a");
      plot.href = `/elements/${e.body.element}/orders.png`;
      plot.target = "_blank";
      plot.className = "grating-orders";
      plot.textContent = "orders.png";
      plot.title = "the grating's order efficiencies against the wavelength (its wave solution)";
      li.append(" ", plot);
      return li;
    }
    const grid = (ll.state?.sensors ?? []).find((s) => s.packs);   // a sensor a pack can be driven by
    if (e.applied && grid && type) li.append(" ", ...packControls(e, grid));
    return li;
  }));
}

/** Library elements' types by id ("microstructure", "grating"), read once each (GET /elements/{id}); the list is
 *  drawn again when one arrives. */
const elementTypes = new Map();

function elementType(id) {
  if (!elementTypes.has(id)) {
    elementTypes.set(id, null);
    getJSON(`/elements/${id}`).then((summary) => {
      elementTypes.set(id, summary.type);
      redrawElements();
    }).catch(() => elementTypes.delete(id));
  }
  return elementTypes.get(id);
}

/** Packs started from this page, by assignment id: {busy, text, result} (kept across redraws of the list). */
const packs = new Map();

function redrawElements() {
  listElements(ll.state?.elements ?? [], ll.state?.nodes ?? []);
}

/** The "pack" button of an assignment, its progress, and once done the plot and a "use it" button. */
function packControls(assignment, grid) {
  const p = packs.get(assignment.id) ?? {};
  const button = document.createElement("button");
  button.textContent = "pack";
  button.title = `pack this element's dots until ${grid.name ?? "the first grid sensor"} reads min/max 0.8 ` +
    "(a job; a density element only)";
  button.disabled = Boolean(p.busy);
  button.onclick = () => pack(assignment, grid);
  const state = document.createElement("span");
  state.className = "muted pack-state";
  state.textContent = p.text ?? "";
  if (p.result) {
    const plot = document.createElement("a");
    plot.href = p.result.png_url;
    plot.target = "_blank";
    plot.textContent = "pack.png";
    const use = document.createElement("button");
    use.textContent = "use it";
    use.className = "pack-use";
    use.title = `put element ${p.result.element.slice(0, 12)} in place of ${p.result.packed_from.slice(0, 12)}`;
    use.onclick = async () => {
      try {
        await putJSON(`/scenes/${sceneId}/elements/${assignment.id}`, { element: p.result.element });
      } catch (err) {
        fail(`switch refused: ${err.message}`);
      }
    };
    state.append(" ", plot, " ", use);
  }
  return [button, " ", state];
}

/** Pack an element against a grid sensor (POST /elements/{id}/pack) and follow the job; its result offers the
 *  switch of the scene's assignment to the packed element (PUT /scenes/{id}/elements/{aid}). */
async function pack(assignment, grid) {
  const show = (entry) => { packs.set(assignment.id, entry); redrawElements(); };
  show({ busy: true, text: "starting…" });
  try {
    let job = await postJSON(`/elements/${assignment.body.element}/pack`,
      { scene: sceneId, assignment: assignment.id, sensor: grid.id, target: 0.8, max_iterations: 8 });
    while (!["succeeded", "failed", "cancelled"].includes(job.status)) {
      await new Promise((r) => setTimeout(r, 500));
      job = await getJSON(job.url);
      const p = job.progress ?? {};
      if (p.uniformity != null) {   // the uniformity of iteration p.measured (p.iteration is the one running)
        show({ busy: true, text: `iteration ${p.measured ?? p.iteration}: min/max ${p.uniformity.toFixed(3)} ± ` +
          `${(p.uniformity_stderr ?? 0).toFixed(3)}, ${(p.seconds ?? 0).toFixed(1)} s` });
      }
    }
    const r = job.result;
    if (!r?.element) throw new Error(job.error ?? job.status);
    show({ busy: false, result: r, text: `${job.status}: min/max ${r.uniformity.toFixed(3)} ± ` +
      `${r.uniformity_stderr.toFixed(3)} after ${r.iterations} iterations (${r.stopped})` });
  } catch (err) {
    show({ busy: false, text: "" });
    fail(`pack refused: ${err.message}`);
  }
}

function drawSensors() {
  const sensors = ll.state?.sensors ?? [];
  const scale = new Scale(ll.scale, vmaxOf(sensors));
  viewer?.setSensors(sensors, scale);
  viewer?.setSurfaces(sensors, scale);
  drawLegend($("legend"), $("legend-labels"), scale);
  $("sensors").replaceChildren(...sensors.map((s) => {
    const li = document.createElement("li");
    const name = s.name ?? `${s.type} sensor ${s.id.slice(0, 8)}`;
    li.textContent = s.result
      ? `${name}: ${formatLux(s.result.min_lux)} – ${formatLux(s.result.max_lux)} (${s.result.photons.toLocaleString()} photons)`
      : `${name}: not simulated at this revision `;
    if (s.simulate) {   // the service says which sensors the page simulates and shows
      const button = document.createElement("button");
      button.textContent = "simulate";
      button.title = "trace photons for this sensor (a job of at most 10 s)";
      button.onclick = () => simulate(s.id);
      li.append(" ", button);
    }
    return li;
  }));
}

function status(extra = "") {
  const s = ll.state?.scene;
  $("status").className = "muted";
  $("status").textContent = s ? `revision ${s.revision} · ${ll.state.instances.length} parts · ${ll.connection}${extra}` : "";
}

function fail(text) {
  ll.error = text;
  $("status").className = "error";
  $("status").textContent = text;
}

// ------------------------------------------------------------------------------------------- side panel

function listChanges(push) {
  const items = [];
  if (push) {
    for (const kind of ["added", "moved", "geometry_changed", "removed", "renamed"]) {
      const n = push.counts?.[kind] ?? 0;
      if (!n) continue;
      const li = document.createElement("li");
      if (CHANGE_COLOURS[kind]) {
        const sw = document.createElement("span");
        sw.className = "swatch";
        sw.style.background = CHANGE_COLOURS[kind];
        li.append(sw, " ");
      }
      li.append(`${kind.replace("_", " ")}: ${n}`);
      items.push(li);
    }
  }
  const head = document.createElement("li");
  head.className = "muted";
  head.textContent = push ? `revision ${push.revision}${items.length ? "" : ": nothing changed"}` : "none through this service process yet";
  $("changes").replaceChildren(head, ...items);
}

/** Jobs of this scene, by id (updated from `job` events between reads of the state). */
const jobs = new Map();

function listJobs(list) {
  if (list) { jobs.clear(); for (const j of list) jobs.set(j.id, j); }
  const items = [...jobs.values()].map((j) => {
    const li = document.createElement("li");
    const p = j.progress ?? {};
    const what = j.kind === "sensor" ? `sensor ${(j.sensor ?? "").slice(0, 8)}`
      : j.kind === "pack" ? `pack of ${(j.element ?? "").slice(0, 8)}, iteration ${p.iteration ?? 0}`
      : `${j.points ?? "?"} points`;
    const err = p.worst_relative_error != null ? `, worst error ${(100 * p.worst_relative_error).toFixed(1)} %` : "";
    const left = p.seconds_left != null && j.status === "running" ? `, ~${p.seconds_left.toFixed(1)} s left` : "";
    li.textContent = `${what}: ${j.status}, ${(p.photons ?? 0).toLocaleString()} photons${err}${left}`;
    const total = (p.seconds ?? 0) + (p.seconds_left ?? 0);
    const done = j.status === "succeeded" ? 1 : total > 0 ? (p.seconds ?? 0) / total : 0;
    const bar = document.createElement("div");
    bar.className = "bar";
    bar.innerHTML = `<div style="width:${Math.round(100 * done)}%"></div>`;
    li.append(bar);
    return li;
  });
  $("jobs").replaceChildren(...(items.length ? items : [Object.assign(document.createElement("li"), { className: "muted", textContent: "none" })]));
  ll.jobs = [...jobs.values()];
}

async function simulate(sensorId) {
  try {
    await postJSON(`/scenes/${sceneId}/sensors/${sensorId}/simulate?mode=async`, { max_seconds: 10 });
  } catch (err) {
    fail(`simulation refused: ${err.message}`);
  }
}

/** "render this view": the viewer's camera as two camera sensors of the scene, a coarse one (40 rows) and the
 *  full one (120 rows), each simulated as a job: the coarse image shows within about a second, then the full one
 *  refines pass by pass (growing time budgets) until its median pixel error is at most 2 % or the passes are spent.
 *  A push (a new revision) starts the passes again on the new scene; a newer render replaces the running one. */
const RENDER_PASSES = [{ coarse: true, max_seconds: 1 }, { max_seconds: 2 }, { max_seconds: 6 }, { max_seconds: 20 }];
const RENDER_TARGET = 0.02;   // median pixel relative error to stop at

function medianRelativeError(r) {
  const lum = r.luminance.flat(), err = r.stderr.flat();
  const rel = lum.map((v, k) => (v > 0 ? err[k] / v : NaN)).filter((x) => Number.isFinite(x)).sort((a, b) => a - b);
  return rel.length ? rel[Math.floor(rel.length / 2)] : NaN;
}

async function runJob(sensorId, budget, seed) {
  let job = await postJSON(`/scenes/${sceneId}/sensors/${sensorId}/simulate?mode=async`, { ...budget, seed });
  while (!["succeeded", "failed", "cancelled"].includes(job.status)) {
    await new Promise((r) => setTimeout(r, 200));
    job = await getJSON(job.url);
  }
  if (job.status !== "succeeded") throw new Error(job.error ?? job.status);
  return job.result;
}

async function renderPasses(render) {
  const state = $("render-state");
  for (const [k, pass] of RENDER_PASSES.entries()) {
    if (ll.render !== render) return;                       // a newer render (or a push) took over
    const sensor = pass.coarse ? render.coarse : render.full;
    const t0 = performance.now();
    const r = await runJob(sensor, { max_seconds: pass.max_seconds }, k);
    if (ll.render !== render) return;
    const lum = r.luminance.flat(), median = medianRelativeError(r);
    render.passes.push({ pass: k, coarse: !!pass.coarse, width: r.width, height: r.height, photons: r.photons,
                         seconds: r.seconds, wall: (performance.now() - t0) / 1000, median, revision: r.revision });
    render.result = r;
    state.textContent = `pass ${k + 1}: ${r.width} × ${r.height}, ${Math.min(...lum).toPrecision(3)} – ` +
      `${Math.max(...lum).toPrecision(3)} cd/m², median error ${(100 * median).toFixed(1)} % ` +
      `(${r.photons.toLocaleString()} paths, revision ${r.revision}; Reinhard tone map)`;
    Object.assign($("render"), { src: `/scenes/${sceneId}/sensors/${sensor}/image.png?revision=${r.revision}&pass=${k}`,
                                 hidden: false });
    if (!pass.coarse && median <= RENDER_TARGET) break;
  }
  render.done = true;
}

async function renderView() {
  const button = $("render-view"), state = $("render-state");
  if (!viewer) return;
  button.disabled = true;
  try {
    const stamp = new Date().toLocaleTimeString();
    const full = await postJSON(`/scenes/${sceneId}/sensors`, { ...viewer.cameraBody(120), name: `view ${stamp}` });
    const coarse = await postJSON(`/scenes/${sceneId}/sensors`,
                                  { ...viewer.cameraBody(40), name: `view ${stamp} (coarse)` });
    const render = { sensor: full.id, full: full.id, coarse: coarse.id, passes: [], result: null, done: false };
    ll.render = render;
    state.textContent = "rendering: a coarse image first…";
    await renderPasses(render);
  } catch (err) {
    state.textContent = `render refused: ${err.message}`;
  } finally {
    button.disabled = false;
  }
}

/** After a push, the image starts again on the new revision. */
function renderAgain() {
  const old = ll.render;
  if (!old) return;
  const render = { ...old, passes: [], result: null, done: false, restarts: (old.restarts ?? 0) + 1 };
  ll.render = render;
  renderPasses(render).catch((err) => { $("render-state").textContent = `render refused: ${err.message}`; });
}
$("render-view").onclick = renderView;

// ------------------------------------------------------------------------------------------- picking

function materialText(m) {
  if (!m) return "—";
  const extra = Object.entries(m).filter(([k]) => k !== "type").map(([k, v]) => `${k} ${v}`).join(", ");
  return extra ? `${m.type} (${extra})` : m.type;
}

/** Name chain of a node (root first), from the state's node list. */
function nameChain(uuid) {
  const nodes = new Map(ll.state.nodes.map((n) => [n.uuid, n]));
  const names = [];
  for (let n = nodes.get(uuid); n; n = nodes.get(n.parent)) names.unshift(n.name);
  return names.join(" › ");
}

function showPick(hit) {
  const panel = $("pick");
  if (!hit) { panel.className = "muted"; panel.textContent = "nothing there"; ll.lastPick = null; return; }
  const info = { point: hit.point };
  const rows = [["point", hit.point.map((x) => x.toFixed(3)).join(", ") + " m"]];
  if (hit.surface) {
    const rec = hit.surface.rec;
    const node = rec.node ? ll.state.nodes.find((n) => n.uuid === rec.node) : null;
    const object = rec.object ? ll.state.objects.find((o) => o.id === rec.object) : null;
    info.node = node ? { uuid: node.uuid, path: node.path, chain: nameChain(node.uuid) } : null;
    info.object = object ? { id: object.id, name: object.name } : null;
    info.material = rec.material;
    if (node) rows.push(["node", node.path], ["names", info.node.chain], ["uuid", node.uuid]);
    if (object) rows.push(["object", `${object.name ?? "(unnamed)"} (owned by the simulation)`]);
    rows.push(["material", materialText(rec.material)]);
    const tally = hit.surface.tally;   // the model's surface coloured by a surface sensor: that triangle's lux
    if (tally && !hit.sensor) {
      const k = hit.surface.triangle;
      Object.assign(info, { triangle: k, lux: tally.lux[k], stderr: tally.stderr[k],
        surfaceSensor: { id: tally.sensor.id, name: tally.sensor.name } });
      rows.push(["lux", `${formatLux(info.lux)} ± ${formatLux(info.stderr)} (triangle ${k}, ` +
        `${tally.sensor.name ?? tally.sensor.id.slice(0, 8)})`]);
    }
  }
  if (hit.sensor) {
    const { sensor: s, i, j } = hit.sensor;
    info.sensor = { id: s.id, name: s.name, i, j };
    rows.push(["sensor", `${s.name ?? s.id.slice(0, 8)}, cell (${i}, ${j})`]);
    if (s.result) {
      info.lux = s.result.lux[j][i];
      info.stderr = s.result.stderr[j][i];
      rows.push(["lux", `${formatLux(info.lux)} ± ${formatLux(info.stderr)}`]);
    } else {
      rows.push(["lux", "not simulated at this revision"]);
    }
  }
  ll.lastPick = info;
  const dl = document.createElement("dl");
  for (const [k, v] of rows) dl.append(Object.assign(document.createElement("dt"), { textContent: k }),
    Object.assign(document.createElement("dd"), { textContent: v }));
  panel.className = "";
  panel.replaceChildren(dl);
  if (hit.surface && !hit.sensor) panel.append(measureButton(hit.surface));
}

/** The answer's tessellation error beside its Monte Carlo one: the bound and, where asked, the estimate and its
 * cost (error_budget, lx; issue 42). Empty where the scene has no curved mirror or glass mesh. */
function tessellationText(a) {
  const b = a.error_budget;
  if (!b?.tessellation) return "";
  let text = `tessellation: at most ${formatLux(b.tessellation[0])} (bound)`;
  if (b.tessellation_estimate) {
    text += `, estimated ${formatLux(b.tessellation_estimate[0])} ± ${formatLux(b.tessellation_estimate_stderr[0])}` +
      ` (${b.tessellation_estimate_levels} refinements, ${b.tessellation_estimate_seconds.toFixed(1)} s)`;
  }
  return text;
}

/** Lux ± error at a picked surface point: a short illuminance query (2 s at most) on the side facing the viewer. */
function measureButton(surface) {
  const button = document.createElement("button");
  button.textContent = "measure lux here (≤ 2 s)";
  button.onclick = async () => {
    button.disabled = true;
    button.textContent = "measuring…";
    const n = surface.normal;
    const eps = 1e-4 * Math.max(viewer.size, 1);
    const radius = Math.min(0.25, Math.max(0.005, 0.02 * viewer.size));
    try {
      const a = await postJSON(`/scenes/${sceneId}/illuminance`, {
        points: [surface.point.map((x, k) => x + eps * n[k])], normals: [n], radius, max_seconds: 2,
      });
      const p = Object.assign(document.createElement("p"), {
        textContent: `${formatLux(a.lux[0])} ± ${formatLux(a.stderr[0])} on a disk of ${radius.toFixed(3)} m (${a.photons.toLocaleString()} photons, ${a.estimator})`,
      });
      button.replaceWith(p);
      const budget = tessellationText(a);
      if (budget) p.after(Object.assign(document.createElement("p"), { className: "budget", textContent: budget }));
      if (ll.lastPick) Object.assign(ll.lastPick, { lux: a.lux[0], stderr: a.stderr[0] });
    } catch (err) {
      button.replaceWith(Object.assign(document.createElement("p"), { className: "error", textContent: err.message }));
    }
  };
  return button;
}

// ------------------------------------------------------------------------------------------- wiring

if (viewer) {
  // a click (not a drag of the camera) picks
  let down = null;
  const canvas = viewer.renderer.domElement;
  canvas.addEventListener("pointerdown", (e) => { down = [e.clientX, e.clientY]; });
  canvas.addEventListener("pointerup", (e) => {
    if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) < 4) showPick(viewer.pick(e.clientX, e.clientY));
    down = null;
  });
}
for (const radio of document.querySelectorAll('input[name="scale"]')) {
  radio.addEventListener("change", () => { ll.scale = radio.value; drawSensors(); });
}
$("highlight").addEventListener("change", () => ll.state && viewer?.setInstances(ll.state, $("highlight").checked));

let timer = null;
const soon = () => { clearTimeout(timer); timer = setTimeout(refresh, 100); };   // events come in bursts
const seen = (name, data) => { ll.events.push({ name, data, at: Date.now() }); if (ll.events.length > 200) ll.events.shift(); };

followEvents(sceneId, {
  hello: (d) => { seen("hello", d); soon(); },
  scene: (d) => { seen("scene", d); soon(); },
  push: (d) => { seen("push", d); soon(); renderAgain(); },
  result: (d) => { seen("result", d); soon(); },
  resync: (d) => { seen("resync", d); soon(); },
  job: (d) => { seen("job", d); jobs.set(d.id, d); listJobs(); },
  deleted: (d) => { seen("deleted", d); fail("this scene was deleted"); },
}, (state) => { ll.connection = state; status(); });

refresh();
