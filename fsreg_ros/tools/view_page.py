"""The live view's page: one HTML document with its style and script (no external resources).

The page carries the snapshot it was served with (drawn at once), and the script opens
``/events`` (Server-Sent Events, see :mod:`fsreg_ros.tools.view`) and
redraws on every snapshot.  Elements carry ``data-*`` attributes (entity, domain,
property, origin, source, strength, forget-at) so a browser test can read what the page shows:
a WM entry's ``data-strength`` is how the consultant held it at its ``wm/state``'s time
(``age 0, 2 episodes``, plus ``, activation 1.23`` under rule ``activation``; ``""`` when
unknown), the same words as a REG word's.
"""

#: Where the server puts the snapshot the page draws first (JSON, ``</`` escaped).
SNAPSHOT_SLOT = "/*SNAPSHOT*/null"

PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>fsreg: working memory, live</title>
<style>
  body { font: 14px/1.4 system-ui, sans-serif; margin: 0; color: #1b1b1b; background: #fafafa; }
  header { padding: 8px 16px; background: #263238; color: #eceff1; display: flex; gap: 24px; align-items: baseline; }
  header h1 { font-size: 16px; margin: 0; }
  #ready.yes { color: #a5d6a7; } #ready.no { color: #ef9a9a; }
  main { display: grid; grid-template-columns: minmax(280px, 1fr) 2fr; gap: 16px; padding: 16px; }
  section { background: white; border: 1px solid #ddd; border-radius: 6px; padding: 8px 12px; }
  h2 { font-size: 14px; margin: 4px 0 8px; }
  .line { padding: 4px 0; border-bottom: 1px solid #eee; }
  .line .who { font-weight: 600; margin-right: 6px; }
  .line.robot .who { color: #1565c0; } .line.human .who { color: #6a1b9a; }
  .line .meta { color: #666; font-size: 12px; }
  .prop { display: inline-block; padding: 0 6px; margin: 1px 2px; border-radius: 10px; font-size: 12px; }
  .prop.wm { background: #c8e6c9; } .prop.ltm { background: #e0e0e0; }
  table { border-collapse: collapse; width: 100%; }
  td, th { text-align: left; padding: 3px 6px; border-bottom: 1px solid #eee; vertical-align: top; }
  .entry { display: inline-block; margin: 1px 3px; padding: 1px 6px; border-radius: 4px; background: #fff3e0;
           border: 1px solid #ffcc80; font-size: 12px; }
  .entry .why { color: #795548; } .entry .held { color: #33691e; } .entry .left { color: #b71c1c; }
  .settings { color: #444; font-size: 12px; margin-bottom: 6px; }
  .error { color: #b71c1c; }
</style>
</head>
<body>
<header><h1>fsreg working memory</h1><span>clock <b id="clock">-</b> s</span>
  <span id="ready" class="no">connecting...</span><span id="graph"></span></header>
<main>
  <section><h2>Dialogue</h2><div id="dialogue"></div></section>
  <section><h2>Working memory (least recently used first)</h2><div id="domains"></div></section>
</main>
<script>
"use strict";
const INITIAL = /*SNAPSHOT*/null;
const $ = (id) => document.getElementById(id);
function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) { if (v !== null && v !== undefined) e.setAttribute(k, v); }
  if (text !== undefined) e.textContent = text;
  return e;
}
function origin(o) { return o ? (o.cause + (o.turn !== null && o.turn !== undefined ? " @" + o.turn : "")) : "?"; }
function strength(g) {
  if (!g) return "";
  const act = g.activation === null || g.activation === undefined ? ""
    : ", activation " + (typeof g.activation === "number" ? g.activation.toFixed(2) : g.activation);
  return "age " + g.age + ", " + g.episodes + (g.episodes === 1 ? " episode" : " episodes") + act;
}
function render(s) {
  $("clock").textContent = s.time === null ? "-" : s.time.toFixed(1);
  $("ready").textContent = s.ready ? "ready" : "not ready";
  $("ready").className = s.ready ? "yes" : "no";
  $("graph").textContent = s.graph ? "graph " + s.graph : "";
  const d = $("dialogue"); d.replaceChildren();
  for (const line of s.dialogue) {
    const div = el("div", {"class": "line " + line.speaker, "data-speaker": line.speaker});
    div.append(el("span", {"class": "who"}, line.speaker === "robot" ? "robot:" : "human:"));
    div.append(el("span", {"class": "text"}, line.text || ""));
    if (line.speaker === "robot" && line.properties) {
      const props = el("div", {"class": "props"});
      for (const p of line.properties) {
        const src = p.source || "ltm";
        const held = src === "wm" ? strength(p.strength) : "";
        props.append(el("span", {"class": "prop " + src, "data-property": p.property, "data-source": src,
                                 "data-strength": held,
                                 "title": src === "wm" ? "from WM (" + origin(p.origin) + ")" : "from LTM"},
                        p.property + " (" + src.toUpperCase() + (held ? "; " + held : "") + ")"));
      }
      div.append(props);
      div.append(el("div", {"class": "meta"}, "target " + line.target + ", t=" + line.time));
    } else if (line.speaker === "human") {
      const who = line.resolved ? "resolved " + line.resolved : (line.status || "");
      const when = line.time !== undefined ? ", t=" + line.time : "";
      div.append(el("div", {"class": "meta", "data-resolved": line.resolved || ""}, who + when));
    }
    if (line.error) div.append(el("div", {"class": "error"}, line.error));
    d.append(div);
  }
  d.scrollTop = d.scrollHeight;
  const root = $("domains"); root.replaceChildren();
  for (const [domain, dom] of Object.entries(s.domains)) {
    const sec = el("div", {"class": "domain", "data-domain": domain});
    sec.append(el("h2", {}, domain + " (incarnation " + dom.incarnation + ")"));
    const m = dom.memory || {};
    const settings = Object.entries(m).filter(([k, v]) => v !== null).map(([k, v]) => k + "=" + v).join(", ");
    const tick = dom.next_tick !== null ? "; next decay tick at " + dom.next_tick : "";
    const memory = "memory: " + (settings || "?") + tick;
    sec.append(el("div", {"class": "settings", "data-memory": JSON.stringify(m)}, memory));
    const table = el("table");
    for (const [entity, entries] of Object.entries(dom.entities)) {
      const tr = el("tr", {"class": "entity", "data-entity": entity});
      tr.append(el("th", {}, entity));
      const td = el("td");
      for (const e of entries) {
        const held = strength(e.strength);
        const span = el("span", {"class": "entry", "data-property": e.property, "data-origin": origin(e.origin),
                                 "data-forget-at": e.forget_at, "data-strength": held});
        span.append(el("b", {}, e.property));
        span.append(el("span", {"class": "why"}, " " + origin(e.origin)));
        if (held) span.append(el("span", {"class": "held"}, "; " + held));
        if (e.forget_at !== null && s.time !== null) {
          const left = Math.max(0, e.forget_at - s.time).toFixed(1);
          span.append(el("span", {"class": "left"}, " forgets in " + left + " s"));
        }
        td.append(span);
      }
      tr.append(td); table.append(tr);
    }
    sec.append(table); root.append(sec);
  }
  document.body.setAttribute("data-version", s.version);
}
let shown = -1;
function show(s) { if (s && s.version !== shown) { shown = s.version; render(s); } }
show(INITIAL);  // the state when the page was served, drawn before anything else loads
function connect() {  // then every change as it happens
  const source = new EventSource("events");
  source.onmessage = (m) => show(JSON.parse(m.data));
  source.onerror = () => { $("ready").textContent = "view disconnected"; $("ready").className = "no"; };
}
connect();
</script>
</body>
</html>
"""
