// The side panel: runs, field, status, steering and replay controls, messages. It sends
// through `send(message)` and never talks to the bus itself: every command is the
// service's own (docs/commands.md, docs/replay.md), acknowledged in the messages list.

const $ = (id) => document.getElementById(id);

export class Panel {
  constructor(send) {
    this.send = send;
    this.nextId = 1;
    this.pending = new Map(); // request id -> what the user did
    this.run = null;
    this.replayEnd = 0;
    this.wire();
  }

  command(kind, args = {}) {
    const id = this.nextId++;
    this.pending.set(id, kind);
    this.send({ type: "command", id, kind, args });
    return id;
  }

  wire() {
    const number = (id) => Number($(id).value);
    $("btn-pause").onclick = () => this.command("pause");
    $("btn-resume").onclick = () => this.command("resume");
    $("btn-step").onclick = () => this.command("step", { count: 1 });
    $("btn-reset").onclick = () => this.command("reset");
    const rate = (v) => this.command("set_contraction", { heart_rate: v });
    $("heart-rate").onchange = () => rate(number("heart-rate"));
    $("heart-rate-slider").onchange = () => { $("heart-rate").value = $("heart-rate-slider").value; rate(number("heart-rate-slider")); };
    $("peak-tension").onchange = () => this.command("set_contraction", { peak_tension: number("peak-tension") });
    $("btn-gravity").onclick = () => this.command("set_gravity", { gravity: ["x", "y", "z"].map((a) => number(`gravity-${a}`)) });
    $("btn-play").onclick = () => this.command("resume");
    $("btn-replay-pause").onclick = () => this.command("pause");
    $("timeline").onchange = () => this.command("seek", { time: number("timeline") });
    $("replay-rate").onchange = () => this.command("set_rate", { rate: number("replay-rate") });
    $("field").onchange = () => this.watch(this.run);
  }

  pushForce() { return Number($("push-force").value); }
  field() { return $("field").value; }

  watch(run) {
    if (run) this.send({ type: "watch", run, field: this.field() });
  }

  hello(msg) {
    $("field").innerHTML = msg.fields.map((f) => `<option value="${f}">${f.replace("_", " ")}</option>`).join("");
    this.controls = msg.controls;
    $("why-not").textContent = msg.controls ? "" : `Controls disabled: ${msg.why_not}`;
    for (const el of document.querySelectorAll(".controls button, .controls input")) el.disabled = !msg.controls;
  }

  runs(list, current) {
    $("runs").innerHTML = "";
    for (const r of list) {
      const li = document.createElement("li");
      li.textContent = `${r.run_id}${r.replay ? " (replay)" : ""} · ${r.state}`;
      li.dataset.run = r.run_id;
      li.className = r.run_id === current ? "current" : "";
      li.onclick = () => this.watch(r.run_id);
      $("runs").appendChild(li);
    }
  }

  topology(msg) {
    this.run = msg.run;
    $("field").value = msg.field;
    $("live-controls").hidden = msg.replay;
    $("replay-controls").hidden = !msg.replay;
    for (const li of $("runs").children) li.className = li.dataset.run === msg.run ? "current" : "";
  }

  status(s) {
    const f = (v, d) => (v === null || v === undefined ? "–" : Number(v).toFixed(d));
    $("st-state").textContent = `${s.state} (${s.mode})`;
    $("st-time").textContent = `${f(s.time_s, 3)} s, frame ${s.frame}`;
    $("st-beat").textContent = s.replay ? "–" : f(s.beat, 2);
    $("st-fps").textContent = f(s.frames_per_second, 1);
    $("st-rtf").textContent = f(s.real_time_factor, 2);
    $("st-iter").textContent = s.solver_iterations;
    $("st-rate").textContent = s.replay ? "–" : `${f(s.heart_rate_bpm, 1)} /min`;
    $("st-version").textContent = `v${s.parameter_version}`;
    if (document.activeElement !== $("heart-rate")) $("heart-rate").value = f(s.heart_rate_bpm, 0);
    if (document.activeElement !== $("peak-tension")) $("peak-tension").value = f(s.peak_tension_pa, 0);
    if (s.replay) {
      this.replayEnd = Math.max(this.replayEnd, (s.recorded_frames - 1) * s.dt_s, s.time_s);
      $("timeline").max = this.replayEnd;
      if (document.activeElement !== $("timeline")) $("timeline").value = s.time_s;
      $("timeline-label").textContent = `${f(s.time_s, 3)} s of ${f(this.replayEnd, 3)} s · ${s.state}`;
    }
  }

  ack(msg) {
    this.pending.delete(msg.id);
    this.message(`${msg.kind}: ${msg.accepted ? "accepted" : "rejected"}: ${msg.reason}`, msg.accepted ? "ok" : "error");
  }

  error(msg) {
    this.pending.delete(msg.id);
    this.message(`error: ${msg.message}`, "error");
  }

  message(text, kind) {
    const li = document.createElement("li");
    li.textContent = text;
    li.className = kind;
    $("messages").prepend(li);
    while ($("messages").children.length > 50) $("messages").lastChild.remove();
  }
}
