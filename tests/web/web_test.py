"""Browser tests of `fiberfem web` (docs/web.md), one ctest entry per case:

    web_test.py CASE FIBERFEM_BIN SOURCE_DIR [OUT_DIR]

Each case starts a real service (or replay), the bridge through `fiberfem web`, Debian's
headless Chromium on the page, and checks what the page shows against what the service
reports to an independent Python client."""

import os
import shutil
import subprocess
import sys
import time

import numpy as np

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

    t0 = rig.js("return window.fiberfem.stats.lastFrame.time_s;")
    a = rig.canvas_image()[:, :-COLOURBAR_PX]
    # 0.28 s of simulated time: from one phase of the beat to another (period 0.83 s).
    rig.wait_js(f"window.fiberfem.stats.lastFrame.time_s >= {t0 + 0.28}", timeout=30, what="0.28 s of run time")
    b = rig.canvas_image()[:, :-COLOURBAR_PX]
    sa, sb = silhouette(a), silhouette(b)
    print(f"silhouette: {sa.mean():.3f} and {sb.mean():.3f} of the view")
    assert sa.mean() > 0.05 and sb.mean() > 0.05, "a screenshot is blank"
    inside = sa | sb
    changed = (np.abs(a - b).sum(axis=2) > 30) & inside
    print(f"pixels changed inside the heart: {changed.sum() / inside.sum():.3f}")
    assert changed.sum() > 0.02 * inside.sum(), "the heart looks the same a third of a beat later"
    if out_dir:
        rig.driver.save_screenshot(os.path.join(out_dir, "web-page.png"))


CASES = {"stream": case_stream}


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
