// The page of `fiberfem web` (docs/web.md): connects to the bridge's WebSocket, draws the
// newest frame once per display refresh and asks for the next only after drawing it (so a
// slow page skips frames instead of queueing them), and steers through the panel.
import { Colouring } from "./colours.js";
import { CirculationPanel } from "./circulation.js";
import { decodeFrame } from "./frames.js";
import { Panel } from "./panel.js";
import { HeartView } from "./view.js";

const $ = (id) => document.getElementById(id);
const view = new HeartView($("view"));
const colouring = new Colouring();
const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws${location.search}`);
ws.binaryType = "arraybuffer";
const send = (msg) => { if (ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(msg)); };
const panel = new Panel(send);
const circulation = new CirculationPanel();

// What the tests and scripts/web_measure.py read: frames drawn, bytes, publish-to-paint
// latency of each drawn frame (ms, the service's source timestamp to the end of render()).
const stats = { frames: 0, bytes: 0, latencies: [], started: performance.now(), lastFrame: null, topology: null, acks: [], errors: [] };
window.fiberfem = { stats, panel, view, send, colouring, ws, circulation };

let pending = null;   // the newest frame received, not drawn yet
let regionNames = [];

ws.onmessage = (event) => {
  if (event.data instanceof ArrayBuffer) {
    try {
      pending = decodeFrame(event.data);
    } catch (e) {
      panel.message(`bad frame: ${e.message}`, "error");
      send({ type: "ready" });
    }
    return;
  }
  const msg = JSON.parse(event.data);
  switch (msg.type) {
    case "hello": panel.hello(msg); break;
    case "runs": panel.runs(msg.runs, panel.run); if (!panel.run && msg.runs.length === 0) panel.message("no run on the domain yet", ""); break;
    case "topology":
      regionNames = msg.region_names;
      colouring.reset(msg.field, regionNames);
      view.setSurface(msg.triangles, msg.rest);
      panel.topology(msg);
      stats.topology = { run: msg.run, vertices: msg.vertices, triangles: msg.triangles.length / 3, replay: msg.replay };
      if (circulation.run !== msg.run) { circulation.clear(msg.run); stats.circulation = null; }
      if (pending) send({ type: "ready" }); // dropped undrawn: ask for one of the new surface
      pending = null;
      break;
    case "status": panel.status(msg); stats.status = msg; break;
    case "circulation":
      circulation.update(msg);
      stats.circulation = { run: msg.run, now: msg.now, beat: msg.beat, points: circulation.points.length, messages: (stats.circulation?.messages ?? 0) + 1 };
      break;
    case "ack": panel.ack(msg); stats.acks.push(msg); break;
    case "error": panel.error(msg); stats.errors.push(msg); break;
    default: panel.message(`unknown message '${msg.type}'`, "error");
  }
};
ws.onclose = () => panel.message("connection to the bridge closed", "error");

function draw(now) {
  requestAnimationFrame(draw);
  circulation.drawIfDue(now);
  if (pending && view.mesh && pending.vertices * 3 === view.mesh.geometry.attributes.position.array.length) {
    const f = pending;
    pending = null;
    if (f.field !== colouring.field) {  // the bridge fell back from a field the run cannot show
      colouring.reset(f.field, regionNames);
      $("field").value = f.field;
    }
    const rgb = view.colours();
    const [lo, hi] = colouring.paint(f.values, rgb);
    view.setFrame(f.positions, rgb);
    view.render();
    colouring.drawBar($("colourbar-ramp"), { max: $("colourbar-max"), mid: $("colourbar-mid"), min: $("colourbar-min"), title: $("colourbar-title") }, lo, hi);
    stats.frames += 1;
    stats.bytes += f.bytes;
    stats.latencies.push(performance.timeOrigin + performance.now() - f.source_ms);
    if (stats.latencies.length > 10000) stats.latencies.splice(0, 5000);
    stats.lastFrame = { frame: f.frame, time_s: f.time_s, parameter_version: f.parameter_version, field: f.field, vertices: f.vertices };
    send({ type: "ready" });
  } else if (pending && view.mesh) {
    pending = null; // a frame of a surface this page no longer shows
    send({ type: "ready" });
  } else if (view.needsRender) {
    view.render();
  }
}
requestAnimationFrame(draw);

// Shift + hold on the wall pushes it: the force (the push force along the view ray) stays
// on the node nearest the point while the button is held.
let pushing = false;
$("view").addEventListener("pointerdown", (e) => {
  if (!e.shiftKey || e.button !== 0 || !panel.controls) return;
  const hit = view.pick(e);
  if (!hit) return;
  e.preventDefault();
  e.stopImmediatePropagation();
  view.controls.enabled = false;
  pushing = true;
  const magnitude = panel.pushForce();
  const id = panel.nextId++;
  stats.press = { id, point: hit.point, force: hit.direction.map((d) => d * magnitude) };
  send({ type: "press", id, point: hit.point, force: stats.press.force });
  panel.message(`push at (${hit.point.map((v) => v.toFixed(4)).join(", ")}) m, ${magnitude} N`, "");
}, { capture: true });
const release = () => {
  if (!pushing) return;
  pushing = false;
  view.controls.enabled = true;
  send({ type: "release", id: panel.nextId++ });
};
window.addEventListener("pointerup", release);
window.addEventListener("pointercancel", release);
