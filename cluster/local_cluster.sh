#!/usr/bin/env bash
# A multi-node Ray cluster on this one machine, for trying genr8 on a "cluster" without one:
# a head node plus N worker nodes, each a separate Ray node with its own raylet and a few CPUs.
#
#   cluster/local_cluster.sh start [WORKERS]   # default 2 workers; prints the address to use
#   cluster/local_cluster.sh status
#   cluster/local_cluster.sh stop              # stops exactly the processes it started (PID files)
#
# Settings (environment variables):
#   GENR8_RAY_PORT        the head's port                      (default 6390)
#   GENR8_HEAD_CPUS       CPUs the head offers to islands      (default 1)
#   GENR8_WORKER_CPUS     CPUs each worker node offers         (default 1)
#   GENR8_CLUSTER_DIR     where PID files and logs are kept    (default /tmp/genr8-local-cluster-$USER)
#   GENR8_DASHBOARD=1     start Ray's dashboard, for `ray job submit --address http://127.0.0.1:8265`
#   GENR8_DASHBOARD_PORT  its port                             (default 8265)
#   GENR8_DASHBOARD_AGENT_PORT  the head's job agent's HTTP port  (default 52366)
#   RAY                   the ray command                      (default: the one on PATH)
#   PYTHON                a Python with ray installed          (default: the python next to RAY)
#
# Then:  genr8 run examples/quick.toml --run-dir runs/on-cluster --address 127.0.0.1:6390
set -euo pipefail

PORT="${GENR8_RAY_PORT:-6390}"
HEAD_CPUS="${GENR8_HEAD_CPUS:-1}"
WORKER_CPUS="${GENR8_WORKER_CPUS:-1}"
DASHBOARD_PORT="${GENR8_DASHBOARD_PORT:-8265}"
AGENT_PORT="${GENR8_DASHBOARD_AGENT_PORT:-52366}"
STATE="${GENR8_CLUSTER_DIR:-/tmp/genr8-local-cluster-${USER:-$(id -u)}}"
RAY="${RAY:-$(command -v ray || true)}"
PY="${PYTHON:-$(dirname "${RAY:-/usr/bin/ray}")/python}"
[[ -x "$PY" ]] || PY="$(command -v python3)"
export RAY_USAGE_STATS_ENABLED=0
# Ray's token authentication: `ray start --head` turns it on when ~/.ray/auth_token exists (any local
# ray.init creates one) but worker nodes do not, and then cannot join. Decide once, for every node.
if [[ -z "${RAY_AUTH_MODE:-}" && -f "${RAY_AUTH_TOKEN_PATH:-$HOME/.ray/auth_token}" ]]; then
  export RAY_AUTH_MODE=token
fi

die() { echo "local_cluster.sh: $*" >&2; exit 2; }

wait_for_port() {  # wait until something accepts connections on 127.0.0.1:$1
  local tries=0
  until "$PY" - "$1" <<'PY' 2>/dev/null
import socket, sys
socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=1).close()
PY
  do
    tries=$((tries + 1)); [[ $tries -gt 60 ]] && return 1; sleep 1
  done
}

wait_for_nodes() {  # wait until the cluster has $1 alive nodes
  local tries=0
  until "$PY" - "$PORT" "$1" <<'PY' 2>/dev/null
import sys, ray
ray.init(address=f"127.0.0.1:{sys.argv[1]}", logging_level="ERROR", log_to_driver=False)
alive = sum(1 for n in ray.nodes() if n["Alive"])
ray.shutdown()
sys.exit(0 if alive >= int(sys.argv[2]) else 1)
PY
  do
    tries=$((tries + 1)); [[ $tries -gt 30 ]] && return 1; sleep 2
  done
}

start_node() {  # start_node NAME ARGS...: one `ray start --block` in its own session, PID to a file
  local name="$1"; shift
  setsid nohup "$RAY" start --block --disable-usage-stats "$@" >"$STATE/$name.log" 2>&1 < /dev/null &
  echo $! >"$STATE/$name.pid"
}

cmd_start() {
  local workers="${1:-2}"
  [[ -n "$RAY" ]] || die "the 'ray' command was not found; install genr8 with its dependencies first"
  [[ "$workers" =~ ^[0-9]+$ ]] || die "WORKERS must be a number, got '$workers'"
  if compgen -G "$STATE/*.pid" >/dev/null; then die "already started (PID files in $STATE); stop it first"; fi
  mkdir -p "$STATE"
  local dashboard=(--include-dashboard false)
  if [[ "${GENR8_DASHBOARD:-0}" == 1 ]]; then
    # the head's dashboard agent takes job submissions; its own port, so another Ray on this machine
    # (which holds Ray's default agent port) cannot leave the cluster without one
    dashboard=(--include-dashboard true --dashboard-port "$DASHBOARD_PORT"
               --dashboard-agent-listen-port "$AGENT_PORT")
  fi
  start_node head --head --port "$PORT" --num-cpus "$HEAD_CPUS" "${dashboard[@]}"
  wait_for_port "$PORT" || { cmd_stop; die "the head did not come up; see $STATE/head.log"; }
  # one node at a time: nodes on one machine register by IP, and concurrent starts race
  for i in $(seq 1 "$workers"); do
    start_node "worker$i" --address "127.0.0.1:$PORT" --num-cpus "$WORKER_CPUS"
    if ! wait_for_nodes $((i + 1)); then
      echo "local_cluster.sh: warning: worker $i did not report alive; see $STATE/worker$i.log" >&2
    fi
  done
  echo "Ray cluster: head + $workers worker node(s), $((HEAD_CPUS + workers * WORKER_CPUS)) CPUs"
  echo "address: 127.0.0.1:$PORT"
  echo "run on it:  genr8 run CONFIG --run-dir DIR --address 127.0.0.1:$PORT"
  if [[ "${GENR8_DASHBOARD:-0}" == 1 ]]; then
    # `ray job submit` must use the cluster's authentication mode too: print it in the line to copy
    local auth=""
    if [[ -n "${RAY_AUTH_MODE:-}" ]]; then auth="RAY_AUTH_MODE=$RAY_AUTH_MODE "; fi
    echo "or submit:  ${auth}ray job submit --address http://127.0.0.1:$DASHBOARD_PORT --runtime-env cluster/runtime_env.yaml -- python -m genr8_dist.cli run CONFIG --run-dir /abs/DIR"
  fi
  echo "stop it:    $0 stop"
}

cmd_stop() {
  compgen -G "$STATE/*.pid" >/dev/null || { echo "nothing to stop (no PID files in $STATE)"; return 0; }
  local pids=() f pid
  # workers first, the head last
  for f in $(ls "$STATE"/worker*.pid 2>/dev/null) "$STATE/head.pid"; do
    [[ -f "$f" ]] || continue
    pid="$(cat "$f")"
    if kill -0 "$pid" 2>/dev/null; then kill -TERM "$pid" 2>/dev/null || true; pids+=("$pid"); fi
  done
  for _ in $(seq 1 20); do
    local alive=0
    for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
    [[ $alive -eq 0 ]] && break
    sleep 0.5
  done
  for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && kill -KILL "$pid" 2>/dev/null || true; done
  rm -f "$STATE"/*.pid
  # `ray start` recorded this cluster as the machine's current one; forget it, as `ray stop` does
  local current="${TMPDIR:-/tmp}/ray/ray_current_cluster"
  if [[ -f "$current" ]] && grep -q ":$PORT\$" "$current"; then rm -f "$current"; fi
  echo "stopped ${#pids[@]} Ray node(s)"
}

cmd_status() {
  compgen -G "$STATE/*.pid" >/dev/null || { echo "not running"; return 0; }
  local f
  for f in "$STATE"/*.pid; do
    if kill -0 "$(cat "$f")" 2>/dev/null; then state=running; else state=dead; fi
    echo "$(basename "$f" .pid): pid $(cat "$f") $state"
  done
  echo "address: 127.0.0.1:$PORT"
}

case "${1:-}" in
  start) shift; cmd_start "$@" ;;
  stop) cmd_stop ;;
  status) cmd_status ;;
  *) echo "usage: $0 start [WORKERS] | stop | status" >&2; exit 2 ;;
esac
