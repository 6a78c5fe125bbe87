"""A sweep on a real Ray cluster: a head node and a worker node started as separate processes
(``ray start --head`` and ``ray start --address``, what a lab runs on its machines), a smoke
study run against it with ``address=``, and its records compared with a local sweep's.

The cluster lives in a network namespace of its own (``unshare -n``, as root) that has only
the loopback interface: Ray otherwise swaps 127.0.0.1 for the machine's outward address, and
this test must send nothing anywhere but loopback. Bounded in time; the nodes are stopped by
their own process ids at the end (never ``ray stop``, which stops every Ray on the machine).
"""

import os
import pathlib
import shutil
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("ray")
ROOT = pathlib.Path(__file__).resolve().parent.parent
RAY = pathlib.Path(sys.executable).with_name("ray")

# the study run on both: bc_demos at smoke on reacher4 (5 cells), as tests/test_sweep.py runs it
SWEEP = """
import dataclasses, sys
from dc_lesson import budget
from dc_lesson.experiments import sweep
tiny = dataclasses.replace(budget.get("smoke"), bc_demo_counts=(2,), sweep_seeds_reacher=2)
address = sys.argv[2] or None
r = sweep.run("bc_demos", tiny, only=["task=reacher4"], root=sys.argv[1], address=address,
              cpus=None if address else 1, progress=False, aggregate=False)
assert (r.ran, r.failed) == (5, []), (r.ran, r.failed)
"""

# inside the namespace: loopback up, a head and a worker node (one CPU each), a driver that
# waits for both, the sweep against them; the nodes stopped whatever happened
CLUSTER = """
set -u
ip link set lo up
export RAY_USAGE_STATS_ENABLED=0 OMP_NUM_THREADS=1
# Ray's nodes authenticate with a token (on by default since Ray 2.5x): every node and the
# driver get the same one, as a lab would hand it to its machines
export RAY_AUTH_TOKEN=$("{python}" -c 'import secrets; print(secrets.token_hex(32))')
export RAY_AUTH_MODE=token
tmp=$(mktemp -d /tmp/rcXXXX)   # short: a Unix socket path has at most 107 characters
"{ray}" start --block --head --port=6379 --num-cpus=1 --include-dashboard=false \
    --disable-usage-stats --temp-dir="$tmp" > "{out}/head.log" 2>&1 &
head=$!
# the head is up when `ray status` answers (a loaded machine takes tens of seconds)
for i in $(seq 120); do
  "{ray}" status --address=127.0.0.1:6379 > /dev/null 2>&1 && break
  sleep 1
done
"{ray}" start --block --address=127.0.0.1:6379 --num-cpus=1 --disable-usage-stats \
    > "{out}/worker.log" 2>&1 &
worker=$!
timeout 300 "{python}" - <<'PY'
import ray, sys, time
t0 = time.time()
while True:   # the nodes may still be registering
    try:
        ray.init(address="127.0.0.1:6379", logging_level="ERROR")
        break
    except ConnectionError:
        if time.time() - t0 > 120:
            raise
        time.sleep(2)
while ray.cluster_resources().get("CPU", 0) < 2 and time.time() - t0 < 120:
    time.sleep(1)
sys.exit(0 if ray.cluster_resources().get("CPU", 0) >= 2 else 3)
PY
rc=$?
if [ $rc -eq 0 ]; then
  timeout 600 "{python}" -c '{sweep}' "{out}/cluster" 127.0.0.1:6379
  rc=$?
fi
kill -TERM $worker $head 2>/dev/null
wait $worker $head 2>/dev/null
rm -rf "$tmp"
exit $rc
"""


def _env():
    env = dict(os.environ, OMP_NUM_THREADS="1", RAY_USAGE_STATS_ENABLED="0",
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    env.setdefault("MUJOCO_GL", "egl")
    return env


def _records(root):
    from dc_lesson.experiments import cells
    out = {}
    for p in sorted(pathlib.Path(root).glob("*/*/*.json")):
        r = cells.read_record(p)
        out[str(p.relative_to(root))] = (r["cell"], r["config"], r["result"])
    return out


# Opt-in (DC_LESSON_CLUSTER_TEST=1): on this 2-core machine `ray start` itself fails about half
# the time under any load (its raylet waits a fixed 15 s for its agent and the node a fixed 30
# s for the raylet; "The current node timed out during startup"), which would make CI's
# verdict a coin flip that says nothing about the sweep.
@pytest.mark.skipif(os.environ.get("DC_LESSON_CLUSTER_TEST") != "1",
                    reason="the two-node Ray cluster test is opt-in: DC_LESSON_CLUSTER_TEST=1")
def test_a_sweep_on_a_two_node_cluster_writes_the_records_a_local_sweep_does(tmp_path):
    if os.geteuid() != 0 or not shutil.which("unshare") or not shutil.which("ip"):
        pytest.skip("a network namespace of its own needs root, unshare and ip")
    script = tmp_path / "cluster.sh"
    script.write_text(CLUSTER.format(ray=RAY, python=sys.executable, out=tmp_path,
                                     sweep=SWEEP.replace("'", "'\\''")))
    on_cluster = subprocess.run(["unshare", "-n", "bash", str(script)], env=_env(),
                                timeout=900, capture_output=True, text=True)
    logs = "".join((tmp_path / f).read_text()[-1500:] for f in ("head.log", "worker.log")
                   if (tmp_path / f).exists())
    assert on_cluster.returncode == 0, (f"exit {on_cluster.returncode}: "
                                        + on_cluster.stderr[-3000:] + logs)
    local = subprocess.run([sys.executable, "-c", SWEEP, str(tmp_path / "local"), ""],
                           env=_env(), timeout=600, capture_output=True, text=True)
    assert local.returncode == 0, local.stderr[-3000:]
    a, b = _records(tmp_path / "cluster"), _records(tmp_path / "local")
    assert len(a) == 5 and a == b
