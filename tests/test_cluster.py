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
#
# Node startup under load (Ray 2.60). Two waits are fixed in Ray's code: the raylet gives each
# agent (dashboard agent, runtime-env agent) 15 s to write its port file and aborts when one is
# late (`WaitForPersistedPort(..., 15000)` in NodeManager's constructor, a constant in the
# raylet binary; ray start never hands the raylet the dashboard agent's listen port, so that
# wait always happens), and ray/_private/node.py waits `raylet_start_wait_time_s = 30` s for
# its raylet to register. Two read RAY_<name> and are raised: node.py's look-up of its node
# retries inside Ray's C++ for the config `raylet_start_wait_time_s` (default 30 s) before
# node.py checks its own 30 s, so 120 lets a slow raylet register; and the raylet gives its
# runtime-env agent `agent_register_timeout_ms` (default 30000) to answer. A node whose raylet
# aborts anyway is started again: start_node sees the abort in the raylet's log.
CLUSTER = """
set -u
ip link set lo up
export RAY_USAGE_STATS_ENABLED=0 OMP_NUM_THREADS=1
export RAY_raylet_start_wait_time_s=120 RAY_agent_register_timeout_ms=120000
# Ray's nodes authenticate with a token (on by default since Ray 2.5x): every node and the
# driver get the same one, as a lab would hand it to its machines
export RAY_AUTH_TOKEN=$("{python}" -c 'import secrets; print(secrets.token_hex(32))')
export RAY_AUTH_MODE=token
tmp=$(mktemp -d /tmp/rcXXXX)   # short: a Unix socket path has at most 107 characters
pid=; head=; worker=
stop() {{   # one `ray start --block` by its pid: SIGTERM stops its node, SIGKILL after 30 s
  [ -n "$1" ] || return 0
  kill -TERM "$1" 2>/dev/null
  for i in $(seq 30); do kill -0 "$1" 2>/dev/null || break; sleep 1; done
  kill -KILL "$1" 2>/dev/null
  wait "$1" 2>/dev/null
}}
# start_node LOG NAME ARGS...: `ray start --block ARGS` in the background, at most 3 tries of
# at most 150 s each (none begun after 240 s of the script); 0 with the node's pid in $pid once
# it printed "Ray runtime started." (its raylet registered). A try ends early when its raylet
# died (a failed check in raylet.out/err, e.g. an agent's port file 15 s late); a failed try's
# processes die with its `ray start` (Ray's fate-sharing), and each try has a temp dir of its own.
start_node() {{
  local log=$1 name=$2 try i; shift 2
  for try in 1 2 3; do
    [ $try -eq 1 ] || [ $SECONDS -lt 240 ] || break
    echo "=== try $try at $SECONDS s" >> "$log"
    "{ray}" start --block "$@" --temp-dir="$tmp/$name$try" >> "$log" 2>&1 &
    pid=$!
    for i in $(seq 150); do
      sleep 1
      grep -q "Ray runtime started" "$log" && return 0
      kill -0 $pid 2>/dev/null || break
      grep -qs "Check failed" "$tmp/$name$try"/session_*/logs/raylet.* && break
    done
    stop $pid
    tail -n 3 "$tmp/$name$try"/session_*/logs/raylet.out >> "$log" 2>/dev/null
  done
  pid=
  return 1
}}
rc=3
if start_node "{out}/head.log" h --head --port=6379 --num-cpus=1 --include-dashboard=false \
     --disable-usage-stats; then
  head=$pid
  sleep 5   # let the head's own start-up work (a prestarted worker) settle before the worker's
  if start_node "{out}/worker.log" w --address=127.0.0.1:6379 --num-cpus=1 \
       --disable-usage-stats; then
    worker=$pid
    timeout 90 "{python}" - <<'PY'
import ray, sys, time
t0 = time.time()
while True:   # both nodes are up; the driver's own connection may still need a retry
    try:
        ray.init(address="127.0.0.1:6379", logging_level="ERROR")
        break
    except ConnectionError:
        if time.time() - t0 > 30:
            raise
        time.sleep(2)
while ray.cluster_resources().get("CPU", 0) < 2 and time.time() - t0 < 60:
    time.sleep(1)
sys.exit(0 if ray.cluster_resources().get("CPU", 0) >= 2 else 3)
PY
    rc=$?
  fi
fi
echo "node start-up over after $SECONDS s (exit $rc)" >> "{out}/head.log"
if [ $rc -eq 0 ]; then
  timeout 300 "{python}" -c '{sweep}' "{out}/cluster" 127.0.0.1:6379
  rc=$?
fi
stop "$worker"
stop "$head"
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


# Opt-in (DC_LESSON_CLUSTER_TEST=1) because it needs root, unshare and ip for its network
# namespace, and takes about 1.5 min. `ray start` used to fail here about half the time under
# load ("The current node timed out during startup"); with RAY_raylet_start_wait_time_s and
# RAY_agent_register_timeout_ms raised and a node retried when its raylet aborts (see CLUSTER),
# it passed 3 of 3 runs in a row on the 2-core machine (2026-12-05, 89-93 s each, load 3.7 with
# two training jobs running beside it); both nodes were up about 27 s in, on the first try
# each, so the retry was not needed in those runs. The raylet's 15 s wait for its agents cannot
# be raised: a machine loaded enough to miss it on 3 tries in a row still fails the test.
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
