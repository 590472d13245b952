"""Driven by tests/service/serve_test.cpp: the Python client against a real service.
Prints one JSON object with what it saw; exits non-zero on any failure."""

import json
import sys

import numpy as np
from fiberfem_client import Client

run = sys.argv[1]
c = Client("python-test")
assert c.resolve_run(run, 20) == run
topo = c.topology(run)
first = c.next_state(run)
states = list(c.states(run, count=3))
assert all(b.frame > a.frame for a, b in zip(states, states[1:]))
ok = c.send(run, "set_gravity", {"gravity": [0.0, 0.0, 9.81]})
bad = c.send(run, "set_time_step", {"dt": float("nan")})
after = c.next_state(run, ok.frame)
print(json.dumps({
    "nodes": int(topo.rest_positions.shape[0]),
    "elements": int(topo.tets.shape[0]),
    "rest_sum": float(np.float64(topo.rest_positions).sum()),
    "positions_shape": list(first.positions.shape),
    "frames_increase": True,
    "ok_accepted": ok.accepted,
    "bad_accepted": bad.accepted,
    "bad_reason": bad.reason,
    "version_after": after.parameter_version,
    "ok_version": ok.parameter_version,
}))
