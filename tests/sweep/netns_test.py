"""Several hosts: a Dask scheduler on one host, a worker on each of two others, the sweep's
client beside the scheduler; the tiny sweep completes across them. The hosts are network
namespaces the test makes (as tests/service/netns_test.cpp does): veth pairs to a bridge in
a hub namespace, link-local addresses in 169.254.214.0/24 (never routed; the traffic stays
inside the namespaces). They share this file system, as a cluster shares a network file
system. Needs root and `ip netns`; exit 77 (skipped) otherwise."""

import os
import shutil
import subprocess
import sys

from sweep_support import BIN, TINY, Tally, cleanup, scratch, table, wait_for

IP = next((p for p in ("/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip") if os.access(p, os.X_OK)), "ip")
VENV_BIN = os.path.dirname(os.environ.get("FIBERFEM_PYTHON", sys.executable))
TAG = str(os.getpid() % 100000)
HUB = f"ffsw-hub-{TAG}"
HOSTS = [f"ffsw-{TAG}-{h}" for h in range(3)]  # 0: scheduler and client, 1 and 2: workers
PORT = 8786


def address(h):
    return f"169.254.214.{h + 1}"


def ip(*args):
    p = subprocess.run([IP, *args], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {p.stderr.strip()}")


def build_network():
    ip("netns", "add", HUB)
    ip("-n", HUB, "link", "set", "lo", "up")
    ip("-n", HUB, "link", "add", "br0", "type", "bridge")
    ip("-n", HUB, "link", "set", "br0", "up")
    for h, ns in enumerate(HOSTS):
        ip("netns", "add", ns)
        ip("-n", ns, "link", "set", "lo", "up")
        ip("-n", ns, "link", "add", "eth0", "type", "veth", "peer", "name", f"p{h}", "netns", HUB)
        ip("-n", ns, "addr", "add", address(h) + "/24", "dev", "eth0")
        ip("-n", ns, "link", "set", "eth0", "up")
        ip("-n", HUB, "link", "set", f"p{h}", "master", "br0")
        ip("-n", HUB, "link", "set", f"p{h}", "up")


def delete_network():
    for ns in HOSTS + [HUB]:
        subprocess.run([IP, "netns", "del", ns], capture_output=True)


def on_host(h, argv, **kw):
    env = {k: v for k, v in os.environ.items() if not k.startswith("DASK_")}
    env["DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT"] = "20s"
    return subprocess.Popen([IP, "netns", "exec", HOSTS[h], *argv], env=env, **kw)


def main():
    if os.geteuid() != 0 or not shutil.which(IP) and not os.path.exists(IP):
        print("skipped: needs root and ip netns")
        return 77
    try:
        ip("netns", "add", HUB + "-probe")
        ip("netns", "del", HUB + "-probe")
    except RuntimeError as e:
        print(f"skipped: cannot create a network namespace here ({e})")
        return 77
    t = Tally()
    out, logs = scratch("netns"), scratch("netns-logs")
    procs = []
    try:
        build_network()
        sched = f"tcp://{address(0)}:{PORT}"
        procs.append(on_host(0, [f"{VENV_BIN}/dask", "scheduler", "--host", address(0), "--port", str(PORT),
                                 "--no-dashboard"], stdout=open(f"{logs}/s.out", "w"), stderr=subprocess.STDOUT))
        for h in (1, 2):
            procs.append(on_host(h, [f"{VENV_BIN}/dask", "worker", sched, "--host", address(h), "--nworkers", "1",
                                     "--nthreads", "1", "--no-dashboard", "--name", f"host{h}"],
                                 stdout=open(f"{logs}/w{h}.out", "w"), stderr=subprocess.STDOUT))
        client = on_host(0, [BIN, "sweep", TINY, "--scheduler", sched, "--workers", "2", "--out", out],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        stdout, stderr = client.communicate(timeout=300)
        t.check(client.returncode == 0, f"sweep across hosts exit {client.returncode}: {stderr[-3000:]}")
        t.check("Dask scheduler tcp://169.254.214.1:8786, 2 workers" in stderr, f"2 workers joined: {stderr[:500]}")
        if client.returncode == 0:
            df = table(out)
            t.check(len(df) == 8 and (df["status"] != "error").all(), f"every row: {list(df['status'])}")
            t.check((df["status"] == "completed").sum() == 7, "7 completed, the refused one a row")
            pids = {int(w.rsplit(":", 1)[1]) for w in df["worker"].dropna()}
            hosts = {h: _pids_in(HOSTS[h]) for h in (1, 2)}
            t.check(all(pids & hosts[h] for h in (1, 2)), f"rows from both worker hosts: {pids} in {hosts}")
            t.check(not pids & _pids_in(HOSTS[0]), "no configuration ran on the scheduler's host")
    except RuntimeError as e:
        t.check(False, str(e))
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        delete_network()
        for f in sorted(os.listdir(logs)) if t.failed else []:
            print(f"--- {f}\n" + open(os.path.join(logs, f)).read()[-3000:])
        cleanup(out, logs)
    return t.finish()


def _pids_in(ns) -> set:
    p = subprocess.run([IP, "netns", "pids", ns], capture_output=True, text=True)
    return {int(x) for x in p.stdout.split()}


if __name__ == "__main__":
    sys.exit(main())
