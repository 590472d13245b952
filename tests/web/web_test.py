"""Browser tests of `fiberfem web` (docs/web.md), one ctest entry per case:

    web_test.py CASE FIBERFEM_BIN SOURCE_DIR [OUT_DIR]

Each case starts a real service (or replay), the bridge through `fiberfem web`, Debian's
headless Chromium on the page, and checks what the page shows against what the service
reports to an independent Python client."""

import io
import os
import shutil
import socket
import subprocess
import sys
import time

import numpy as np
from PIL import Image

from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import Select

from harness import Rig, silhouette

COLOURBAR_PX = 120  # the colour bar's strip at the canvas's right edge (clients/web/src/style.css)


def case_stream(rig: Rig, out_dir: str):
    """Two screenshots a third of a beat apart are non-blank and differ inside the heart; the
    page's surface is the topology's boundary as the witness reads it."""
    rig.serve()
    rig.bridge()
    rig.browser()
    rig.wait_js("window.fiberfem.stats.frames >= 2", what="two frames drawn")
    topo = rig.witness().topology(rig.run_id)
    shown = rig.js("return window.fiberfem.stats.topology;")
    assert shown["vertices"] == np.unique(topo.triangles).size, (shown, np.unique(topo.triangles).size)
    assert shown["triangles"] == topo.triangles.shape[0], shown

    # 0.28 s of simulated time: from one phase of the beat to another (period 0.83 s). On a
    # loaded machine the wait may overshoot towards the same phase a beat later: a pair
    # that shows no change is taken again (three pairs at most).
    for attempt in range(3):
        t0 = rig.js("return window.fiberfem.stats.lastFrame.time_s;")
        a = rig.canvas_image()[:, :-COLOURBAR_PX]
        rig.wait_js(f"window.fiberfem.stats.lastFrame.time_s >= {t0 + 0.28}", timeout=30, what="0.28 s of run time")
        b = rig.canvas_image()[:, :-COLOURBAR_PX]
        sa, sb = silhouette(a), silhouette(b)
        print(f"silhouette: {sa.mean():.3f} and {sb.mean():.3f} of the view")
        assert sa.mean() > 0.05 and sb.mean() > 0.05, "a screenshot is blank"
        inside = sa | sb
        changed = (np.abs(a - b).sum(axis=2) > 30) & inside
        print(f"pixels changed inside the heart: {changed.sum() / inside.sum():.3f}")
        if changed.sum() > 0.02 * inside.sum():
            break
    assert changed.sum() > 0.02 * inside.sum(), "the heart looks the same a third of a beat later"
    if out_dir:  # the page as docs/web.md shows it (docs/images/web.png is a copy)
        os.makedirs(out_dir, exist_ok=True)
        assert rig.driver.save_screenshot(os.path.join(out_dir, "web-page.png"))


def case_heart_rate(rig: Rig, out_dir: str):
    """Moving the heart-rate slider (keyboard, as a user would) changes the rate the service reports."""
    rig.serve()
    rig.bridge()
    rig.browser()
    rig.wait_js("window.fiberfem.stats.status && window.fiberfem.panel.controls", what="status and controls")
    assert rig.witness().status(rig.run_id).heart_rate_bpm == 72
    slider = rig.driver.find_element("id", "heart-rate-slider")
    slider.click()  # the thumb moves to the click: the middle, 115
    slider.send_keys(*([Keys.ARROW_LEFT] * 25))
    want = float(slider.get_attribute("value"))
    assert want == 90, want
    rig.wait_js("window.fiberfem.stats.acks.filter(a => a.kind === 'set_contraction' && a.accepted).length >= 2",
                what="accepted rate changes")
    reported = wait_status(rig, lambda s: s.heart_rate_bpm == want)
    print(f"the service reports {reported.heart_rate_bpm} /min after the slider moved to {want}")
    rig.wait_js(f"document.getElementById('st-rate').textContent.startsWith('{want:.1f}')", what="the page's rate")


def case_runs(rig: Rig, out_dir: str):
    """The page lists every run on the domain and switches to the one clicked, in the field chosen."""
    rig.serve()
    other = f"{rig.run_id}-cantilever"
    rig.start([rig.bin, "serve", "--builtin", "cantilever", "--run-id", other, "--threads", "1"], "serve-cantilever")
    rig.witness().resolve_run(other, wait_s=30)
    rig.bridge()
    rig.browser()
    rig.wait_js("document.querySelectorAll('#runs li').length === 2", what="both runs listed")
    rig.driver.find_element("css selector", f"#runs li[data-run='{other}']").click()
    shown = rig.wait_js(f"window.fiberfem.stats.topology.run === '{other}' && window.fiberfem.stats.topology", what="the switch")
    topo = rig.witness().topology(other)
    assert shown["vertices"] == np.unique(topo.triangles).size and shown["triangles"] == topo.triangles.shape[0], shown
    Select(rig.driver.find_element("id", "field")).select_by_value("displacement")
    frame = rig.wait_js("(window.fiberfem.stats.lastFrame || {}).field === 'displacement' && window.fiberfem.stats.lastFrame",
                        what="a displacement frame")
    assert frame["vertices"] == shown["vertices"], frame
    print(f"switched to {other}: {shown['vertices']} vertices, {shown['triangles']} triangles, field displacement")


def case_force(rig: Rig, out_dir: str):
    """Shift + hold on the wall applies the push force at the node nearest the point (ack
    shown); the witness sees that node move along the force, most of all nodes; release clears it."""
    rig.serve("--set", "contraction.peak_tension=0")  # a still heart: every motion is the push's
    rig.bridge()
    rig.browser()
    rig.wait_js("window.fiberfem.stats.frames >= 2 && window.fiberfem.panel.controls", what="frames and controls")
    push = rig.driver.find_element("id", "push-force")
    push.clear()
    push.send_keys("0.5", Keys.TAB)
    before = rig.witness().next_state(rig.run_id).positions.astype(np.float64)
    img = rig.canvas_image()[:, :-COLOURBAR_PX]
    ys, xs = np.nonzero(silhouette(img))
    canvas = rig.driver.find_element("id", "view")
    dx = int(np.median(xs)) - canvas.size["width"] // 2
    dy = int(np.median(ys)) - canvas.size["height"] // 2
    ActionChains(rig.driver).move_to_element_with_offset(canvas, dx, dy).key_down(Keys.SHIFT).click_and_hold().perform()
    ack = rig.wait_js("window.fiberfem.stats.acks.find(a => a.kind === 'apply_force')", what="the push's ack")
    assert ack["accepted"] and "on 1 node(s)" in ack["reason"], ack
    press = rig.js("return window.fiberfem.stats.press;")
    time.sleep(1.0)
    held = rig.witness().next_state(rig.run_id).positions.astype(np.float64)
    ActionChains(rig.driver).release().key_up(Keys.SHIFT).perform()
    cleared = rig.wait_js("window.fiberfem.stats.acks.find(a => a.kind === 'clear_force')", what="the release's ack")
    assert cleared["accepted"], cleared
    node = int(np.argmin(np.linalg.norm(before - np.array(press["point"]), axis=1)))
    moved = held - before
    along = moved[node] @ (np.array(press["force"]) / np.linalg.norm(press["force"]))
    sizes = np.linalg.norm(moved, axis=1)
    print(f"node {node}: {along * 1e3:.3f} mm along the push; largest motion {sizes.max() * 1e3:.3f} mm at node {sizes.argmax()}")
    assert along > 1e-5, "the pushed node did not move along the force"
    assert sizes[node] >= 0.5 * sizes.max(), "the push moved other nodes more than the one under the pointer"
    time.sleep(1.0)
    after = rig.witness().next_state(rig.run_id).positions.astype(np.float64)
    assert np.linalg.norm(after[node] - before[node]) < 0.5 * sizes[node], "the wall did not come back after release"


def case_replay(rig: Rig, out_dir: str):
    """A replay is paused and sought from the page; the witness sees the replay where the page put it."""
    archive = os.path.join(rig.dir, "heart.h5")
    subprocess.run([rig.bin, "run", "--builtin", "heart", "--until", "2", "--threads", "1", "--archive", archive],
                   check=True, stdout=subprocess.DEVNULL, env=rig.env)
    rig.replay(archive, "--loop")
    rig.bridge()
    rig.browser()
    rig.wait_js("window.fiberfem.stats.frames >= 2 && !document.getElementById('replay-controls').hidden",
                what="frames and the replay controls")
    rig.driver.find_element("id", "btn-replay-pause").click()
    rig.wait_js("window.fiberfem.stats.acks.find(a => a.kind === 'pause' && a.accepted)", what="pause acknowledged")
    wait_status(rig, lambda s: s.state == "paused")
    # Drag the timeline to 1.25 s (the page seeks on the slider's change).
    rig.js("const t = document.getElementById('timeline'); t.value = 1.25; t.dispatchEvent(new Event('change'));")
    rig.wait_js("window.fiberfem.stats.acks.find(a => a.kind === 'seek' && a.accepted)", what="seek acknowledged")
    s = wait_status(rig, lambda s: abs(s.time_s - 1.25) < 0.02)
    assert s.state == "paused", s.state
    # A frame published before the pause may still arrive after it: wait for the page to
    # draw the sought one (a stale 1.30 s frame passed a "later than 1.2 s" test once).
    shown = rig.wait_js(f"Math.abs(window.fiberfem.stats.lastFrame.time_s - {s.time_s!r}) < 1e-9 && "
                        "window.fiberfem.stats.lastFrame", what="the sought frame drawn")
    print(f"replay paused at {s.time_s:.4f} s (frame {s.frame}); the page draws t = {shown['time_s']:.4f} s")
    assert abs(shown["time_s"] - s.time_s) < 1e-9


def case_bad_input(rig: Rig, out_dir: str):
    """Out-of-range values and malformed WebSocket messages get an error on the page and
    change nothing: same parameter version and rate, still running, frames still drawn."""
    rig.serve()
    rig.bridge()
    rig.browser()
    rig.wait_js("window.fiberfem.stats.frames >= 2 && window.fiberfem.panel.controls", what="frames and controls")
    s0 = rig.witness().status(rig.run_id)
    rate = rig.driver.find_element("id", "heart-rate")
    rate.clear()
    rate.send_keys("1000", Keys.TAB)
    rejected = rig.wait_js("window.fiberfem.stats.acks.find(a => a.kind === 'set_contraction')", what="the rate's answer")
    assert not rejected["accepted"] and "heart_rate" in rejected["reason"], rejected
    bad = ["{not json", "[1, 2]", '{"type": "nope"}', '{"type": "command", "id": -1, "kind": "pause"}',
           '{"type": "command", "id": 1, "kind": "shutdown"}', '{"type": "command", "id": 2, "kind": "pause", "args": [1]}',
           '{"type": "press", "id": 3, "point": [0, 0], "force": [0, 0, 1]}',
           '{"type": "press", "id": 4, "point": [0, 0, "x"], "force": [0, 0, 1]}',
           '{"type": "release", "id": 5}', '{"type": "watch", "run": "no-such-run", "field": "activation"}',
           '{"type": "watch", "run": "%s", "field": "pressure"}' % rig.run_id, '{"type": "ready", "extra": 1}']
    n0 = rig.js("return window.fiberfem.stats.errors.length;")
    for text in bad:
        rig.js("window.fiberfem.ws.send(arguments[0]);", text)
    rig.js("window.fiberfem.ws.send(new Uint8Array([1, 2, 3]));")
    errors = rig.wait_js(f"window.fiberfem.stats.errors.length >= {n0 + len(bad) + 1} && window.fiberfem.stats.errors",
                         what="an error for each bad message")[n0:]
    for text, e in zip(bad + ["binary"], errors):
        print(f"{text[:60]:60s} -> {e['message']}")
    shown = "\n".join(rig.messages())
    assert "not JSON" in shown and "shutdown" in shown and "text messages" in shown, shown
    f0 = rig.frames()
    rig.wait_js(f"window.fiberfem.stats.frames > {f0 + 2}", what="frames after the bad input")
    s1 = rig.witness().status(rig.run_id)
    assert s1.state == "running", s1.state
    assert s1.parameter_version == s0.parameter_version, (s0.parameter_version, s1.parameter_version)
    assert s1.heart_rate_bpm == s0.heart_rate_bpm


def case_token(rig: Rig, out_dir: str):
    """Listening beyond loopback, commands need the printed token: a page without it (or
    with a wrong one) has its controls disabled and its commands refused, one with it
    steers. A --read-only bridge on loopback refuses every page. (The bridge listens on all
    addresses; the browser connects to 127.0.0.1 only.)"""
    rig.serve()
    b = rig.bridge("--listen", "0.0.0.0")
    token = b.wait_for_output(r"commands need the token: (\S+)").group(1)
    assert f"?token={token}" in b.output()
    for query in ("", "?token=wrong"):
        rig.browser(query)
        why = rig.wait_js("document.getElementById('why-not').textContent", what="the reason controls are off")
        assert "token" in why, why
        assert rig.js("return document.getElementById('btn-pause').disabled;")
        rig.js("window.fiberfem.panel.command('pause');")
        e = rig.wait_js("window.fiberfem.stats.errors[0]", what="the refusal")
        assert e["message"].startswith("not permitted"), e
        rig.driver.quit()
    assert rig.witness().status(rig.run_id).state == "running"
    rig.browser(f"?token={token}")
    rig.wait_js("window.fiberfem.panel.controls === true", what="controls on with the token")
    rig.driver.find_element("id", "btn-pause").click()
    rig.wait_js("window.fiberfem.stats.acks.find(a => a.kind === 'pause' && a.accepted)", what="pause acknowledged")
    wait_status(rig, lambda s: s.state == "paused")
    rig.driver.quit()
    rig.bridge("--read-only")
    rig.browser()
    why = rig.wait_js("document.getElementById('why-not').textContent", what="read-only reason")
    assert "read-only" in why, why


def case_cli(rig: Rig, out_dir: str):
    """`fiberfem web`'s own errors: a missing environment, a taken port, a port out of range."""
    def web(*args, env=None):
        return subprocess.run([rig.bin, "web", *args], env=env or rig.env, capture_output=True, text=True, timeout=30)
    r = web(env=dict(rig.env, FIBERFEM_WEB_PYTHON="/nonexistent/python"))
    assert r.returncode == 3 and "no Python environment at /nonexistent/python" in r.stderr, r
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        r = web("--port", str(port))
    assert r.returncode == 2 and f"cannot listen on 127.0.0.1 port {port}" in r.stderr, r
    r = web("--port", "70000")
    assert r.returncode != 0 and "--port" in r.stderr, r
    print("missing environment: exit 3; taken port: exit 2; --port 70000 refused")


def case_credit(rig: Rig, out_dir: str):
    """A page that does not ask for frames gets one and then nothing (no backlog); when it
    asks, it gets the newest frame, not the next one. Spoken by a bare WebSocket client."""
    import aiohttp
    import asyncio
    rig.serve()
    rig.bridge()

    async def talk():
        async with aiohttp.ClientSession() as http:
            async with http.ws_connect(f"http://127.0.0.1:{rig.port}/ws") as ws:
                first = await next_frame(ws, 20)
                late = await next_frame(ws, 1.5, must=False)
                assert late is None, "a frame came without being asked for"
                await ws.send_str('{"type": "ready"}')
                second = await next_frame(ws, 5)
                again = await next_frame(ws, 0.5, must=False)
                return first, second, again

    first, second, again = asyncio.run(talk())
    print(f"frame {first} held, then frame {second} after 1.5 s (30 states/s published)")
    assert again is None, "two frames for one request"
    assert second - first >= 20, "the frame sent on request was not the newest"


async def next_frame(ws, timeout: float, must: bool = True):
    import asyncio
    import struct
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            msg = await asyncio.wait_for(ws.receive(), max(end - time.monotonic(), 0.01))
        except asyncio.TimeoutError:
            break
        if isinstance(msg.data, bytes):
            return int(struct.unpack_from("<d", msg.data, 8)[0])
    assert not must, f"no frame in {timeout} s"
    return None


def wait_status(rig: Rig, ok, timeout: float = 10):
    end = time.monotonic() + timeout
    while True:
        s = rig.witness().status(rig.run_id)
        if ok(s) or time.monotonic() > end:
            assert ok(s), f"the service's status did not follow: {s}"
            return s


def case_secure(rig: Rig, out_dir: str):
    """Secure mode (docs/security.md): a bridge with the observer identity shows the run with
    its controls disabled and refuses commands; one with the operator identity steers."""
    sec = os.path.join(rig.dir, "sec")
    subprocess.run([os.path.join(rig.source_dir, "scripts", "make_security.sh"), sec], check=True, stdout=subprocess.DEVNULL)
    profile = {who: dict(rig.env, CYCLONEDDS_URI=f"file://{sec}/profiles/{who}.xml") for who in ("service", "observer", "operator")}
    rig.start([rig.bin, "serve", "--builtin", "heart", "--run-id", rig.run_id, "--threads", "1"], "serve", profile["service"])

    def observed_state():  # the run's state as fiberfem ctl with the observer identity reads it
        r = subprocess.run([rig.bin, "ctl", "--run", rig.run_id, "--timeout", "20", "status", "--table", "--count", "1"],
                           env=profile["observer"], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stdout + r.stderr
        return r.stdout

    assert "running" in observed_state()
    rig.bridge(env=profile["observer"])
    rig.browser()
    rig.wait_js("window.fiberfem.stats.frames >= 2", what="frames through the secure observer")
    why = rig.wait_js("document.getElementById('why-not').textContent", what="the reason controls are off")
    assert "observer" in why, why
    assert all(rig.js("return [...document.querySelectorAll('.controls button, .controls input')].map(e => e.disabled);"))
    rig.js("window.fiberfem.panel.command('pause');")
    e = rig.wait_js("window.fiberfem.stats.errors[0]", what="the refusal")
    assert e["message"].startswith("not permitted"), e
    assert "running" in observed_state()
    rig.driver.quit()
    rig.bridge(env=profile["operator"])
    rig.browser()
    rig.wait_js("window.fiberfem.panel.controls === true", what="controls on for the operator")
    rig.driver.find_element("id", "btn-pause").click()
    rig.wait_js("window.fiberfem.stats.acks.find(a => a.kind === 'pause' && a.accepted)", 30, "pause acknowledged")
    assert "paused" in observed_state()


def case_circulation(rig: Rig, out_dir: str):
    """A run with a circulation (the real-time heart coupled to its loop): the page shows its
    pressure-volume loops (LV red, RV blue: both drawn) and, in numbers, exactly the sample of
    the frame it shows as a witness client read it from the service's circulation topic; a
    run without a circulation hides the panel."""
    witness = rig.witness()  # its circulation reader exists before the service publishes
    scene = os.path.join(rig.source_dir, "configs", "scenes", "heart-circulation-realtime.yaml")
    rig.start([rig.bin, "serve", scene, "--run-id", rig.run_id, "--threads", "1"], "serve")
    witness.resolve_run(rig.run_id, wait_s=30)
    rig.bridge()
    rig.browser()
    rig.wait_js("window.fiberfem.stats.circulation && window.fiberfem.stats.circulation.points >= 45", timeout=60,
                what="a second of circulation on the page")
    assert rig.js("return document.getElementById('circulation').hidden;") is False
    seen = {}
    for attempt in range(20):  # the page's newest sample, as the witness read it
        for c in witness.circulation_samples(rig.run_id, wait_s=1.0):
            seen[c.frame] = c
        now = rig.js("return window.fiberfem.stats.circulation.now;")
        if now["frame"] in seen:
            break
    assert now["frame"] in seen, (now["frame"], sorted(seen)[-5:])
    c = seen[now["frame"]]
    mmhg = 133.322387415
    for shown, sample in (("lv_pressure_mmhg", c.lv_pressure_pa / mmhg), ("lv_volume_ml", c.lv_volume_m3 * 1e6),
                          ("rv_pressure_mmhg", c.rv_pressure_pa / mmhg), ("rv_volume_ml", c.rv_volume_m3 * 1e6),
                          ("aortic_pressure_mmhg", c.systemic_arterial_pressure_pa / mmhg)):
        assert abs(now[shown] - sample) <= 1e-9 * max(1.0, abs(sample)), (shown, now[shown], sample)
    print(f"frame {c.frame}: LV {now['lv_pressure_mmhg']:.3f} mmHg {now['lv_volume_ml']:.3f} mL, "
          f"aortic {now['aortic_pressure_mmhg']:.3f} mmHg, as the witness read it")
    # The loops: strokes in the LV's red and the RV's blue on the panel's canvas.
    rig.js("window.fiberfem.circulation.draw();")
    png = rig.driver.find_element("id", "pv-loop").screenshot_as_png
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.int16)
    near = lambda rgb: (np.abs(img - np.array(rgb)).sum(axis=2) < 60).sum()
    red, blue = near((229, 57, 53)), near((30, 136, 229))
    print(f"loop pixels: LV {red}, RV {blue}")
    assert red > 100 and blue > 100, (red, blue)
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        assert rig.driver.save_screenshot(os.path.join(out_dir, "web-circulation.png"))
    # A run without a circulation: the panel hides when the page switches to it.
    plain = rig.run_id + "-plain"
    rig.start([rig.bin, "serve", "--builtin", "heart", "--run-id", plain, "--threads", "1"], "serve-plain")
    witness.resolve_run(plain, wait_s=30)
    rig.wait_js(f"[...document.querySelectorAll('#runs li')].some(li => li.textContent.startsWith('{plain}'))", what="the plain run listed")
    rig.js(f"window.fiberfem.panel.watch('{plain}');")
    rig.wait_js(f"window.fiberfem.stats.topology && window.fiberfem.stats.topology.run === '{plain}'", what="the plain run's surface")
    frames = rig.frames()
    rig.wait_js(f"window.fiberfem.stats.frames >= {frames + 10}", what="frames of the plain run")
    assert rig.js("return document.getElementById('circulation').hidden;") is True
    assert rig.js("return window.fiberfem.stats.circulation;") is None


CASES = {"circulation": case_circulation, "cli": case_cli, "secure": case_secure, "runs": case_runs, "stream": case_stream, "heart_rate": case_heart_rate, "force": case_force, "replay": case_replay,
         "bad_input": case_bad_input, "token": case_token, "credit": case_credit}


def main():
    case, fiberfem_bin, source_dir = sys.argv[1:4]
    out_dir = sys.argv[4] if len(sys.argv) > 4 else ""
    rig = Rig(fiberfem_bin, source_dir)
    ok = False
    try:
        CASES[case](rig, out_dir)
        ok = True
    finally:
        rig.close()
        if not ok:
            for p in rig.procs:
                print(f"--- {p.log_path}\n{p.output()[-3000:]}")
        shutil.rmtree(rig.dir, ignore_errors=True)
    print(f"web {case}: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
