// The Hearth monitor page: one run's tree, what runs now, the activity log, approvals,
// runtime parameters, cancel and stop. Talks to the command API (docs/command-layer.md) and
// follows its event stream; no build step, no external scripts.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const headers = {"Content-Type": "application/json"};
if (token) headers.Authorization = "Bearer " + token;
const $ = id => document.getElementById(id);
const LIVE = new Set(["queued", "running", "halting"]);
const LOG_LINES = 500;

// ---------------------------------------------------------------------------------------
// Values in words: poses, lists and search places instead of JSON or Python reprs
// ---------------------------------------------------------------------------------------
function num(x) {
  if (!Number.isFinite(x) || Number.isInteger(x)) return String(x);
  const a = Math.abs(x);
  return String(Number(x.toFixed(a >= 100 ? 1 : a >= 1 ? 2 : 3)));
}
function deg(rad) { return Math.round(rad * 180 / Math.PI) + "°"; }
// a pose: the server writes a hearth.worldmodel.pose.Pose as its dict (x, y, z, roll, pitch, yaw)
function poseOf(v) {
  if (v && typeof v === "object" && !Array.isArray(v) && typeof v.x === "number"
      && typeof v.y === "number" && typeof v.place !== "string") return v;
  return null;
}
function fmtPose(p) {
  const xyz = [p.x, p.y].concat(typeof p.z === "number" && p.z !== 0 ? [p.z] : []);
  return "(" + xyz.map(num).join(", ") + ") m" + (typeof p.yaw === "number" ? ", yaw " + deg(p.yaw) : "");
}
function fmt(v, depth) {
  depth = depth || 0;
  if (v === null || v === undefined || v === "") return "—";
  if (typeof v === "number") return num(v);
  if (typeof v === "boolean") return v ? "yes" : "no";
  if (typeof v === "string") return v;
  if (Array.isArray(v)) {
    if (!v.length) return "none";
    const many = v.some(x => x && typeof x === "object");
    const shown = v.slice(0, 4).map(x => fmt(x, depth + 1)).join(many ? "; " : ", ");
    return v.length > 4 ? `${shown} … (${v.length} in all)` : shown;
  }
  if (typeof v === "object") {
    if (typeof v.place === "string") {       // a search place or a surface of one
      let s = v.place;
      if (v.parking) s += " from " + v.parking;
      else if (v.surface) s = v.surface.replace(/\//g, " ");
      if (typeof v.probability === "number") s += ` (p ${num(v.probability)})`;
      return s;
    }
    const p = poseOf(v);
    if (p) return fmtPose(p);
    if (depth > 1) return "…";
    const keys = Object.keys(v);
    if (!keys.length) return "none";
    return keys.slice(0, 6).map(k => `${k} ${fmt(v[k], depth + 1)}`).join(", ") + (keys.length > 6 ? ", …" : "");
  }
  return String(v);
}
// A feedback's values (a skill's Skill.report, hearth/skills/base.py: JSON values beside its
// sentence) as a small table; values the sentence already says in these words are left out.
function says(text, words) {
  const quoted = words.replace(/[.*+?^${}()|[\]\\]/g, "\\$&");
  return new RegExp("(^|[^\\w.])" + quoted + "($|[^\\w])").test(text);
}
function unsaid(values, text) {
  return Object.entries(values || {}).filter(([, v]) => !says(text, fmt(v)));
}
function valuesTable(values, text) {
  const rows = unsaid(values, text);
  if (!rows.length) return null;
  const table = el("table", {"class": "values"});
  for (const [k, v] of rows) {
    const tr = el("tr");
    tr.append(el("th", {}, k.replace(/_/g, " ")), el("td", {}, fmt(v)));
    table.append(tr);
  }
  return table;
}
function valuesWords(values, text) {
  return unsaid(values, text).map(([k, v]) => `${k.replace(/_/g, " ")} ${fmt(v)}`).join("\n");
}
const PERCENT = /^(.*?):?\s*(\d{1,3})\s?%$/;
function progressOf(text) {
  const m = PERCENT.exec(text);
  return m ? {prefix: m[1], pct: Math.min(100, Number(m[2]))} : null;
}
function prefixOf(text) {
  const p = progressOf(text);
  if (p) return p.prefix;
  const i = text.lastIndexOf(": ");
  return i > 0 ? text.slice(0, i) : text;
}
function clock(seconds) {
  if (!Number.isFinite(seconds)) return "";
  if (seconds < 100) return seconds.toFixed(1) + " s";
  if (seconds < 600) return Math.round(seconds) + " s";
  const m = Math.floor(seconds / 60), s = Math.round(seconds % 60);
  return `${m}:${String(s).padStart(2, "0")}`;
}
function wallTime(epoch) {
  return typeof epoch === "number" ? new Date(epoch * 1000).toLocaleTimeString([], {hour12: false}) : "";
}

// ---------------------------------------------------------------------------------------
// Small helpers
// ---------------------------------------------------------------------------------------
async function api(path, opts) {
  const r = await fetch("/api" + path, Object.assign({headers}, opts || {}));
  let body = null;
  try { body = await r.json(); } catch (e) { body = null; }
  if (!r.ok) {
    const msg = body && body.error ? body.error.message
      : body && body.detail ? JSON.stringify(body.detail) : String(r.status);
    const err = new Error(msg);
    err.status = r.status;
    throw err;
  }
  return body;
}
function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) if (v !== undefined && v !== null) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}
function bar(pct) {
  const b = el("span", {"class": "bar", "role": "progressbar", "aria-valuenow": String(pct)});
  const i = el("i");
  i.style.width = pct + "%";
  b.append(i);
  return b;
}
function later(fn, ms) {
  let pending = null;
  return () => { if (pending === null) pending = setTimeout(() => { pending = null; fn(); }, ms); };
}
function notice(text) { $("run-notice").textContent = text || ""; }

// ---------------------------------------------------------------------------------------
// The shown run's tree.
//
// The executive reports a node's status when it changes, and a leaf's each time it starts;
// a composite that a parent restarts and that ends as it ended before reports nothing, and
// nodes a restart resets are not reported either. So a node restarted (by a for_each's next
// item, a retry, a selector) would keep the statuses of its earlier activation below it. The
// page keeps, per node, the tick it was last seen ticked (`visit`: a node is ticked when any
// node below it reports) and the tick its current activation began (`start`: ticked again
// after it had ended); a child not ticked since its parent's activation began is shown idle,
// with no text. Events come deepest first within a tick, so the children of a restarted node
// have reported before its own event arrives.
// ---------------------------------------------------------------------------------------
let tree = null;             // {run, root, byPath}
let shown = null;            // the run shown (its JSON)
let following = true;        // show each new run as it starts
let loading = null;          // a run being fetched: its live events wait in `early`
let early = [];
let t0 = null;               // the shown run's first clock time (log times are relative)
let lastT = null;
const logOpen = new Map();   // path -> {li, prefix}: the line a skill's progress rewrites

function buildTree(spec) {
  const byPath = new Map();
  const make = (s, parent) => {
    // a skill's label is "Skill" or "Skill name"
    const skill = s.kind === "skill" ? String(s.label || s.name).split(" ")[0] : null;
    const n = {path: s.path, name: s.name, kind: s.kind, skill, parent,
               rep: s.status || "INVALID", fb: s.feedback || "", values: s.values || {},
               visit: -1, start: -1, children: [], li: null, folded: false, shownStatus: null,
               shownFb: null};
    byPath.set(n.path, n);
    n.children = (s.children || []).map(c => make(c, n));
    return n;
  };
  const root = make(spec.root, null);
  return {run: spec.run, root, byPath};
}
function visited(n, tick) {
  for (let a = n; a; a = a.parent) {
    if (a.visit >= tick) break;          // seen this tick already, and so were its ancestors
    if (a.rep !== "RUNNING") a.start = tick;   // ticked again after it had ended: restarted
    a.visit = tick;
  }
}
function nodeEl(n) {
  const li = el("li", {"class": "node", "data-path": n.path, "data-status": n.rep, "data-kind": n.kind});
  const row = el("div", {"class": "row", "title": n.path});
  const fold = el("button", {"class": "fold", "aria-label": "fold"}, n.children.length ? "▾" : "");
  fold.onclick = () => setFolded(n, !n.folded);
  // a skill shows its skill name when the node has its own; a composite its kind when named
  const kind = n.kind === "skill" ? (n.skill !== n.name ? n.skill : "") : (n.name !== n.kind ? n.kind : "");
  row.append(fold, el("span", {"class": "status"}, ""), el("span", {"class": "name"}, n.name),
             el("span", {"class": "kind"}, kind), el("span", {"class": "fb"}, ""));
  li.append(row);
  if (n.children.length) {
    const ul = el("ul");
    n.children.forEach(c => ul.append(nodeEl(c)));
    li.append(ul);
  }
  n.li = li;
  return li;
}
function setFolded(n, folded) {
  n.folded = folded;
  n.li.classList.toggle("folded", folded);
  n.li.querySelector(":scope > .row .fold").textContent = folded ? "▸" : "▾";
}
const STATUS_WORD = {RUNNING: "running", SUCCESS: "success", FAILURE: "failure", INVALID: "idle"};
function renderTree() {
  if (!tree) { renderProgress([]); return; }
  const running = [];
  const walk = (n, fresh) => {
    const st = fresh ? n.rep : "INVALID";
    const fb = fresh ? n.fb : "";
    if (st !== n.shownStatus) {
      n.shownStatus = st;
      n.li.setAttribute("data-status", st);
      n.li.querySelector(":scope > .row .status").textContent = STATUS_WORD[st] || st.toLowerCase();
    }
    if (fb !== n.shownFb) {
      n.shownFb = fb;
      const span = n.li.querySelector(":scope > .row .fb");
      span.textContent = fb;
      const more = fb ? valuesWords(n.values, fb) : "";
      span.title = more ? fb + "\n" + more : fb;
      const old = n.li.querySelector(":scope > .row .bar");
      if (old) old.remove();
      const p = st === "RUNNING" ? progressOf(fb) : null;
      if (p) span.after(bar(p.pct));
    }
    if (st === "RUNNING" && !n.children.length) running.push(n);
    for (const c of n.children) walk(c, fresh && c.visit >= n.start);
  };
  walk(tree.root, true);
  renderProgress(running);
  if ($("follow-running").checked && running.length) reveal(running[running.length - 1]);
}
const renderSoon = later(renderTree, 40);
function reveal(n) {
  for (let a = n.parent; a; a = a.parent) if (a.folded) setFolded(a, false);
  const box = $("tree-scroll");
  const r = n.li.getBoundingClientRect(), b = box.getBoundingClientRect();
  if (r.top < b.top || r.bottom > b.bottom) box.scrollTop += r.top - b.top - b.height / 3;
}
function renderProgress(running) {
  const ul = $("progress");
  ul.replaceChildren();
  if (!running.length) {
    ul.append(el("li", {"class": "muted"}, shown && LIVE.has(shown.status) ? "nothing running this tick" : "nothing running"));
    return;
  }
  for (const n of running) {
    const li = el("li", {"data-path": n.path});
    const who = el("div", {"class": "who"}, n.skill && n.skill !== n.name ? `${n.name} (${n.skill})` : n.name);
    const text = n.shownFb || "";
    const msg = el("div", {"class": "msg"}, text);
    const p = progressOf(text);
    if (p) msg.append(bar(p.pct));
    li.append(who, msg);
    ul.append(li);
  }
}

// ---------------------------------------------------------------------------------------
// The shown run: header box, log, buttons
// ---------------------------------------------------------------------------------------
function showRun(run, spec, events) {
  shown = run;
  runValues = Object.assign({}, run ? run.params : {});
  tree = spec ? buildTree(spec) : null;
  t0 = lastT = null;
  logOpen.clear();
  $("feedback").replaceChildren();
  const t = $("tree");
  t.replaceChildren();
  if (tree) t.append(nodeEl(tree.root));
  (events || []).forEach(e => runEvent(e.event, e.data));
  renderRun();
  renderTree();
  renderRuns();
  renderParams();
}
function renderRun() {
  const run = shown;
  $("run-id").textContent = run ? run.id : "none";
  $("run-mission").textContent = run ? run.mission : "no run yet";
  const st = $("run-status");
  st.textContent = run ? run.status : "";
  st.setAttribute("data-status", run ? run.status : "");
  $("run-reason").textContent = run && run.result ? run.result.reason : (run && run.reason) || "";
  const box = $("run-params");
  box.replaceChildren();
  if (run) {
    const defaults = Object.fromEntries(((catalogue[run.mission] || {}).parameters || []).map(p => [p.name, p.default]));
    for (const [k, v] of Object.entries(run.params || {})) {
      if (k in defaults && JSON.stringify(defaults[k]) === JSON.stringify(v)) continue;
      if (box.childNodes.length) box.append(", ");
      box.append(el("b", {}, k + " "), fmt(v));
    }
  }
  $("cancel").disabled = !(run && LIVE.has(run.status));
  $("follow").hidden = following;
  $("stop").disabled = ![...runs.values()].some(r => LIVE.has(r.status));
}
function logLine(cls, who, text, path) {
  const li = el("li", {"class": cls, "data-path": path});
  li.append(el("span", {"class": "t"}, t0 !== null && lastT !== null ? clock(lastT - t0) : ""),
            el("span", {"class": "who", "title": path || who}, who),
            el("span", {"class": "msg"}, text));
  const ul = $("feedback");
  ul.prepend(li);
  while (ul.children.length > LOG_LINES) ul.lastChild.remove();
  return li;
}
function setLogText(li, text, values) {
  const msg = li.querySelector(".msg");
  msg.textContent = text;
  const p = progressOf(text);
  if (p) msg.append(bar(p.pct));
  const old = li.querySelector("table.values");
  if (old) old.remove();
  const table = valuesTable(values, text);
  if (table) li.append(table);
  li.querySelector(".t").textContent = t0 !== null && lastT !== null ? clock(lastT - t0) : "";
}
function logFeedback(ev, n) {
  const text = String(ev.message || "");
  const open = logOpen.get(ev.path);
  const prefix = prefixOf(text);
  if (open && open.prefix === prefix && open.li.isConnected) {
    setLogText(open.li, text, ev.values);         // progress rewrites its own line
    if (!progressOf(text)) logOpen.delete(ev.path);
    return;
  }
  const li = logLine("feedback", n ? n.name : ev.path.split("/").pop(), "", ev.path);
  setLogText(li, text, ev.values);
  if (progressOf(text)) logOpen.set(ev.path, {li, prefix});
  else logOpen.delete(ev.path);
}
function nodeName(path) {
  const n = tree && tree.byPath.get(path);
  return n ? n.name : (path || "").split("/").pop();
}
// One event of the shown run: the tree model, the log, the header.
function runEvent(kind, ev) {
  if (typeof ev.t === "number") {
    if (t0 === null) t0 = ev.t;
    lastT = ev.t;
  }
  const n = tree && ev.path ? tree.byPath.get(ev.path) : null;
  if (kind === "status") {
    if (n) {
      if (!ev.halted) visited(n, ev.tick);
      n.rep = ev.status;
    }
  } else if (kind === "feedback") {
    if (n) { visited(n, ev.tick); n.fb = ev.message; n.values = ev.values || {}; }
    logFeedback(ev, n);
  } else if (kind === "write") {
    logLine("write", nodeName(ev.path), `${String(ev.key).split("/").pop()} = ${fmt(ev.value)}`, ev.path);
  } else if (kind === "run") {
    if (shown && ev.run === shown.id) {
      shown.status = ev.state;
      shown.reason = ev.reason;
      if (!LIVE.has(ev.state)) { refreshRunSoon(); renderParamsSoon(); }
    }
    const words = ev.state === "running" && ev.reason === "started" ? "started" : `${ev.state}: ${ev.reason}`;
    logLine("run" + (ev.state === "failed" ? " bad" : ""), "run", words);
  } else if (kind === "submitted") {
    const given = Object.entries(ev.params || {}).map(([k, v]) => `${k} ${fmt(v)}`).join(", ");
    logLine("run", "run", `queued${ev.priority ? " at priority " + ev.priority : ""}${given ? " · " + given : ""}`);
  } else if (kind === "param") {
    runValues[ev.name] = ev.value;
    renderParamsSoon();
    logLine("run", "parameter", `${ev.name} set to ${fmt(ev.value)}`);
  } else if (kind === "restart") {
    logLine("run", nodeName(ev.path), `restarted: ${fmt(ev.changed)} changed`, ev.path);
  } else if (kind === "halted") {
    const slow = (ev.timed_out || []).length ? `; still stopping: ${ev.timed_out.map(nodeName).join(", ")}` : "";
    logLine("run" + (slow ? " bad" : ""), "run", `halted after ${num(ev.waited)} s${slow}`);
  } else if (kind === "stopped") {
    logLine("feedback", nodeName(ev.path), "stopped", ev.path);
  } else if (kind === "approval") {
    const what = ev.state === "pending" ? `asks for approval: autonomy ${ev.level} above the granted ${ev.granted}`
      : `approval ${ev.state}${ev.by ? " by " + ev.by : ""}${ev.reason ? ": " + ev.reason : ""}`;
    logLine("run", ev.skill || "approval", what, ev.path);
  }
}

// ---------------------------------------------------------------------------------------
// Runs list, parameters, approvals
// ---------------------------------------------------------------------------------------
const runs = new Map();       // id -> run JSON, the recent ones
let catalogue = {};           // mission name -> its /api/missions entry
let params = {};              // runtime parameter name -> {value, type, enum, description}
const approvals = new Map();
let runValues = {};           // the shown run's runtime parameter values (given, then changed)

function setRuns(list) {
  runs.clear();
  for (const r of list) runs.set(r.id, r);
  if (shown && runs.has(shown.id)) shown = Object.assign(shown, runs.get(shown.id));
  renderRuns();
  renderRun();
}
const refreshRunsSoon = later(() => api("/runs?limit=20").then(setRuns).catch(() => {}), 150);
const refreshRunSoon = later(() => {
  if (!shown) return;
  api("/runs/" + shown.id).then(r => {
    if (shown && r.id === shown.id) { shown = r; runs.set(r.id, r); renderRun(); renderRuns(); }
  }).catch(() => {});
}, 50);
function renderRuns() {
  const ul = $("runs");
  ul.replaceChildren();
  const order = {running: 0, halting: 0, queued: 1};
  const list = [...runs.values()].sort((a, b) =>
    (order[a.status] ?? 2) - (order[b.status] ?? 2) || b.submitted - a.submitted).slice(0, 12);
  if (!list.length) { ul.append(el("li", {"class": "muted"}, "no runs yet")); return; }
  for (const r of list) {
    const li = el("li", {"data-run": r.id, "aria-current": shown && shown.id === r.id ? "true" : "false",
                         "title": "show this run"});
    const name = el("span", {"class": "rname"}, r.mission + " ");
    const right = el("span", {});
    right.append(el("b", {"class": "state", "data-status": r.status}, r.status));
    if (LIVE.has(r.status)) {
      const b = el("button", {"data-action": "cancel-run", "title": "cancel this run"}, "cancel");
      b.onclick = ev => { ev.stopPropagation(); cancelRun(r.id); };
      right.append(" ", b);
    }
    li.append(name, right, el("span", {"class": "rid"}, r.id));
    li.onclick = () => {
      following = r.status === "running" || r.status === "halting";
      loadRun(r.id);
    };
    ul.append(li);
  }
}
function renderParams() {
  const box = $("params");
  box.replaceChildren();
  const names = Object.keys(params);
  const mine = shown && catalogue[shown.mission]
    ? catalogue[shown.mission].parameters.filter(p => p.runtime).map(p => p.name) : null;
  const first = mine === null ? names : names.filter(n => mine.includes(n));
  const rest = names.filter(n => !first.includes(n));
  // The shown run's own value while it runs (given at submit, then changed); else the value
  // the next run gets.
  const live = shown && LIVE.has(shown.status);
  const value = n => live && first.includes(n) && n in runValues ? runValues[n] : params[n].value;
  if (!first.length) {
    box.append(el("i", {"class": "muted"}, mine === null || !names.length
      ? "no mission declares a runtime parameter" : `${shown.mission} has no runtime parameters`));
  }
  first.forEach(n => box.append(paramEl(n, value(n))));
  if (rest.length) {
    const d = el("details", {"class": "others"});
    d.append(el("summary", {}, `of other missions (${rest.length})`));
    rest.forEach(n => d.append(paramEl(n, value(n))));
    box.append(d);
  }
}
const renderParamsSoon = later(() => renderParams(), 50);
function paramEl(name, value) {
  const p = params[name];
  const row = el("div", {"class": "param", "data-param": name});
  row.append(el("span", {"class": "pname"}, name));
  const err = el("div", {"class": "perr"});
  const put = async value => {
    err.textContent = "";
    try { await api("/parameters/" + encodeURIComponent(name), {method: "PUT", body: JSON.stringify({value})}); }
    catch (e) { err.textContent = e.message; }
  };
  let control;
  if (Array.isArray(p.enum) && p.enum.length) {
    control = el("select", {"aria-label": name});
    for (const v of p.enum) control.append(el("option", {"value": JSON.stringify(v)}, fmt(v)));
    control.value = JSON.stringify(value);
    control.onchange = () => put(JSON.parse(control.value));
  } else if (p.type === "boolean") {
    control = el("select", {"aria-label": name});
    control.append(el("option", {"value": "true"}, "yes"), el("option", {"value": "false"}, "no"));
    control.value = String(Boolean(value));
    control.onchange = () => put(control.value === "true");
  } else {
    control = el("form", {});
    const numeric = p.type === "integer" || p.type === "number";
    const input = el("input", {"type": numeric ? "number" : "text", "aria-label": name,
                               "step": p.type === "integer" ? "1" : "any"});
    input.value = value === null || value === undefined ? "" : String(value);
    control.append(input, " ", el("button", {"type": "submit"}, "Set"));
    control.onsubmit = ev => {
      ev.preventDefault();
      put(numeric ? Number(input.value) : input.value);
    };
  }
  row.append(control);
  if (p.description) row.append(el("div", {"class": "pdesc"}, p.description));
  row.append(err);
  return row;
}
function renderApprovals() {
  const box = $("approvals");
  box.replaceChildren();
  const pending = [...approvals.values()].filter(a => a.state === "pending");
  $("approvals-box").toggleAttribute("data-pending", pending.length > 0);
  if (!pending.length) { box.append(el("i", {"class": "muted"}, "none pending")); return; }
  for (const a of pending) {
    const d = el("div", {"class": "approval", "data-request": a.id});
    d.append(el("div", {"class": "what"}, `${a.skill} wants autonomy ${a.level}`),
             el("div", {"class": "where"}, `granted ${a.granted} · ${a.path}${a.run ? " · " + a.run : ""}`));
    const yes = el("button", {"class": "ok", "data-action": "approve"}, "Approve");
    const no = el("button", {"class": "danger", "data-action": "refuse"}, "Refuse");
    yes.onclick = () => decide(a.id, true);
    no.onclick = () => decide(a.id, false);
    d.append(yes, " ", no);
    box.append(d);
  }
}
async function decide(id, approve) {
  try { await api("/approvals/" + id, {method: "POST", body: JSON.stringify({approve, by: "monitor"})}); }
  catch (e) { notice(`approval ${id}: ${e.message}`); }
}
async function cancelRun(id) {
  notice("");
  try { await api(`/runs/${id}/cancel`, {method: "POST", body: JSON.stringify({reason: "cancelled from the monitor page"})}); }
  catch (e) { notice(`cancel ${id}: ${e.message}`); }
  refreshRunsSoon();
}
$("cancel").onclick = () => { if (shown) cancelRun(shown.id); };
$("stop").onclick = async () => {
  notice("");
  try {
    const r = await api("/stop", {method: "POST", body: JSON.stringify({reason: "stopped from the monitor page"})});
    notice(r.cancelled.length ? `stopped: ${r.cancelled.length} run${r.cancelled.length > 1 ? "s" : ""} cancelled` : "nothing to stop");
  } catch (e) { notice("stop: " + e.message); }
  refreshRunsSoon();
};
$("follow").onclick = () => {
  following = true;
  const live = [...runs.values()].find(r => r.status === "running" || r.status === "halting");
  if (live) loadRun(live.id); else renderRun();
};
$("autonomy").onchange = async ev => {
  try { await api("/autonomy", {method: "PUT", body: JSON.stringify({level: Number(ev.target.value)})}); }
  catch (e) { notice("autonomy: " + e.message); }
};
$("show-writes").onchange = ev => $("feedback").classList.toggle("writes", ev.target.checked);
$("collapse-idle").onclick = () => {
  if (!tree) return;
  const walk = n => { if (n.children.length && n !== tree.root) setFolded(n, n.shownStatus === "INVALID"); n.children.forEach(walk); };
  walk(tree.root);
};
$("expand-all").onclick = () => {
  if (!tree) return;
  const walk = n => { if (n.children.length) setFolded(n, false); n.children.forEach(walk); };
  walk(tree.root);
};

// ---------------------------------------------------------------------------------------
// Loading and the event stream
// ---------------------------------------------------------------------------------------
async function loadRun(runId) {
  loading = runId;
  early = [];
  try {
    const [run, spec, evs] = await Promise.all([
      api("/runs/" + runId), api(`/runs/${runId}/tree`), api(`/runs/${runId}/events?limit=3000`)]);
    if (loading !== runId) return;              // another run was asked for meanwhile
    loading = null;
    showRun(run, spec, evs.events);
    const queued = early;
    early = [];
    queued.filter(([, , seq]) => seq > evs.last_event).forEach(([k, ev, seq]) => onEvent(k, ev, seq));
  } catch (e) {
    if (loading === runId) loading = null;
    notice(`run ${runId}: ${e.message}`);
  }
}
function mapLine(m) {
  const li = el("li", {});
  const what = m.field === "pose" ? "moved" : m.field;
  li.append(el("span", {"class": "t"}, wallTime(m.time)),
            el("span", {"class": "who", "title": m.node}, m.node),
            el("span", {"class": "msg"}, `${what}: ${fmt(m.old)} → ${fmt(m.new)}${m.source ? " · " + m.source : ""}`));
  return li;
}
const mapSeen = new Set();
function addMap(m) {
  const key = [m.node, m.field, m.time].join("|");
  if (mapSeen.has(key)) return;
  mapSeen.add(key);
  const ul = $("map");
  ul.prepend(mapLine(m));
  while (ul.children.length > 200) ul.lastChild.remove();
}
function onEvent(kind, ev, seq) {
  if (loading !== null && ev.run === loading) { early.push([kind, ev, seq]); return; }
  if (kind === "map") { addMap(ev); return; }
  if (kind === "approval") {
    approvals.set(ev.id, ev);
    renderApprovals();
  } else if (kind === "autonomy") {
    $("autonomy").value = String(ev.granted);
  } else if (kind === "param" && ev.run === undefined) {
    if (params[ev.name]) { params[ev.name].value = ev.value; renderParams(); }
    return;
  } else if (kind === "gap") {
    start();                                     // the stream fell behind: load afresh
    return;
  } else if (kind === "day") {                   // hearth serve --schedule (docs/day.md)
    const skip = new Set(["e", "kind", "t", "time", "params"]);
    const rest = Object.entries(ev).filter(([k, v]) => !skip.has(k) && v !== "" && v !== null)
      .map(([k, v]) => `${k} ${fmt(v)}`).join(", ");
    const bad = ["battery_critical", "slot_missed", "interrupted", "emergency"].includes(ev.kind);
    logLine("run" + (bad ? " bad" : ""), "day", `${ev.time} ${ev.kind}${rest ? " · " + rest : ""}`);
    return;
  }
  if (kind === "submitted" || kind === "run") {
    const r = runs.get(ev.run);
    if (r && kind === "run") r.status = ev.state;
    refreshRunsSoon();
    if (kind === "run" && ev.state === "running" && (!shown || ev.run !== shown.id) && following) {
      loadRun(ev.run);
      return;
    }
  }
  if (shown && ev.run === shown.id) {
    runEvent(kind, ev);
    if (kind === "run") renderRun();
    renderSoon();
  }
  if (kind === "run") renderRun();
}
let stream = null;
async function start() {
  if (stream) { stream.close(); stream = null; }
  // The state first: the mission catalogue (which compiles every mission) can take
  // seconds, and until the state is here the page must not claim "no run yet" or
  // autonomy 0 while a mission runs.
  const missionsP = api("/missions");
  const st = await api("/state");
  params = st.parameters || {};
  $("autonomy").value = String(st.granted_autonomy);
  $("autonomy").disabled = false;
  missionsP.then(missions => {
    catalogue = Object.fromEntries(missions.map(m => [m.name, m]));
    renderRun();
    renderParams();
  }).catch(e => notice("missions: " + e.message));
  approvals.clear();
  st.approvals.forEach(a => approvals.set(a.id, a));
  renderApprovals();
  $("map").replaceChildren();
  mapSeen.clear();
  st.map.slice().reverse().forEach(addMap);
  runs.clear();
  (st.runs || []).forEach(r => runs.set(r.id, r));
  following = true;
  showRun(st.run, st.tree, st.events);
  const q = new URLSearchParams({since: String(st.last_event)});
  if (token) q.set("token", token);
  stream = new EventSource("/api/events?" + q);
  for (const kind of ["run", "submitted", "status", "feedback", "write", "param", "restart", "halted",
                      "stopped", "map", "approval", "autonomy", "gap", "day"])
    stream.addEventListener(kind, m => onEvent(kind, JSON.parse(m.data), Number(m.lastEventId)));
  stream.onopen = () => {
    $("conn").textContent = "live";
    $("conn").dataset.state = "live";
    document.body.setAttribute("data-live", "1");
  };
  // EventSource reconnects by itself, sending Last-Event-ID: the server resumes from there.
  stream.onerror = () => {
    $("conn").textContent = "reconnecting…";
    $("conn").dataset.state = "lost";
  };
}
start().catch(e => { $("conn").textContent = "error: " + e.message; $("conn").dataset.state = "lost"; });
