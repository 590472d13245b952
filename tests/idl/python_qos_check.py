"""The Python client's QoS (clients/python/fiberfem_client/client.py) against the QoS that
idl/bus.cpp gives the same entities: for each topic the client uses, the topic's QoS and
the QoS of the client's reader or writer, as Cyclone DDS reports them on live entities
(the C++ side printed by the idl_qos_dump program, the Python side read back from a real
Client). Compared are the policies bus.cpp chooses: reliability, durability, history,
deadline, liveliness and durability service. Exit 0 when they agree; otherwise each
difference is printed and the exit code is 1.

    python tests/idl/python_qos_check.py PATH/TO/idl_qos_dump      (CYCLONEDDS_URI set)
"""

import json
import subprocess
import sys

from fiberfem_client.client import TOPIC_NAMES, Client

INFINITY = 0x7FFFFFFFFFFFFFFF
DURABILITY = {"Volatile": "volatile", "TransientLocal": "transient_local", "Transient": "transient",
              "Persistent": "persistent"}


def kind(policy):
    """'KeepAll' of Policy.History.KeepAll (a policy's type is named 'History.KeepAll')."""
    return type(policy).__name__.split(".")[-1]


def history(h):
    return ["keep_all"] if kind(h) == "KeepAll" else ["keep_last", h.depth]


def policies(qos):
    """The chosen policies of one entity's QoS, in idl_qos_dump's form (Cyclone's defaults
    where a policy is unset, as the dump reports them)."""
    held = {p.__scope__: p for p in qos}
    out = {}
    if "Reliability" in held:
        r = held["Reliability"]
        out["reliability"] = ["reliable" if kind(r) == "Reliable" else "best_effort", r.max_blocking_time]
    if "Durability" in held:
        out["durability"] = DURABILITY[kind(held["Durability"])]
    if "History" in held:
        out["history"] = history(held["History"])
    out["deadline"] = held["Deadline"].deadline if "Deadline" in held else INFINITY
    live = held.get("Liveliness")
    out["liveliness"] = (["automatic" if kind(live) == "Automatic" else "manual", live.lease_duration]
                         if live else ["automatic", INFINITY])
    ds = held.get("DurabilityService")
    out["durability_service"] = ([ds.cleanup_delay, history(ds.history), ds.max_samples, ds.max_instances,
                                  ds.max_samples_per_instance] if ds else [0, ["keep_last", 1], -1, -1, -1])
    return out


def main():
    cpp = json.loads(subprocess.run([sys.argv[1]], check=True, capture_output=True, text=True).stdout)
    client = Client()
    # The client's entities and the role each plays (readers of what a service writes,
    # the writer of commands).
    entities = {"topology": ("reader", client._topology), "state": ("reader", client._state),
                "ack": ("reader", client._ack), "status": ("reader", client._status),
                "circulation": ("reader", client._circulation),
                "command": ("writer", client._command)}
    problems = []
    for key, (role, entity) in entities.items():
        if TOPIC_NAMES[key] != cpp[key]["name"]:
            problems.append(f"{key}: topic name {TOPIC_NAMES[key]!r} != bus.cpp's {cpp[key]['name']!r}")
        for what, qos in (("topic", entity.topic.get_qos()), (role, entity.get_qos())):
            py, want = policies(qos), cpp[key][what]
            if what == "reader":  # a writer's policy (DDS spec); the Python binding drops it on readers
                py.pop("durability_service"), want.pop("durability_service")
            for policy in sorted(set(py) | set(want)):
                if py.get(policy) != want.get(policy):
                    problems.append(f"{key} {what}: {policy} is {py.get(policy)} in Python, "
                                    f"{want.get(policy)} in idl/bus.cpp")
    if set(TOPIC_NAMES) != set(cpp):
        problems.append(f"topics {sorted(TOPIC_NAMES)} in Python, {sorted(cpp)} in idl/bus.cpp")
    for p in problems:
        print(p)
    print(f"{len(entities)} topics, {2 * len(entities)} entities compared: "
          f"{'agree' if not problems else f'{len(problems)} differences'}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
