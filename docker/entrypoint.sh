#!/bin/sh
# illumix container entry point (both images). Configuration comes from environment variables;
# extra arguments after the role are passed on to the command it starts.
#
#   serve        illumix serve over $ILLUMIX_STORE on $ILLUMIX_HOST:$ILLUMIX_PORT   (service image)
#   ray-head     a Ray head node (GCS on $RAY_NODE_IP:$RAY_PORT)                     (render image)
#   ray-worker   a Ray worker node joining $RAY_ADDRESS                              (render image)
#   anything else is run as given, e.g. `illumix render --demo --store /data/store`.
#
# ILLUMIX_TOKEN (or ILLUMIX_TOKEN_FILE, e.g. a Docker/Kubernetes secret file) is the bearer token the
# service requires for uploads and deletes; an empty one counts as unset.
set -eu

if [ -n "${ILLUMIX_TOKEN_FILE:-}" ]; then
  if [ ! -r "$ILLUMIX_TOKEN_FILE" ]; then
    echo "illumix-entrypoint: ILLUMIX_TOKEN_FILE=$ILLUMIX_TOKEN_FILE is not a readable file" >&2
    exit 2
  fi
  ILLUMIX_TOKEN=$(tr -d '\r\n' < "$ILLUMIX_TOKEN_FILE")
  export ILLUMIX_TOKEN
fi
if [ -z "${ILLUMIX_TOKEN:-}" ]; then
  unset ILLUMIX_TOKEN
fi

role=${1:-serve}
[ $# -gt 0 ] && shift

case "$role" in
  serve)
    if [ -z "${ILLUMIX_TOKEN:-}" ]; then
      echo "illumix-entrypoint: no ILLUMIX_TOKEN: uploads and deletes are open to anyone who can" \
           "reach ${ILLUMIX_HOST:-127.0.0.1}:${ILLUMIX_PORT:-8000}" >&2
    fi
    # --create: the service may start before the first render fills the store volume.
    exec illumix serve --create --store "${ILLUMIX_STORE:?set ILLUMIX_STORE to a store directory or fsspec URL}" \
      --host "${ILLUMIX_HOST:-127.0.0.1}" --port "${ILLUMIX_PORT:-8000}" \
      --cache-mb "${ILLUMIX_CACHE_MB:-1024}" "$@"
    ;;
  ray-head | ray-worker)
    command -v ray >/dev/null 2>&1 || {
      echo "illumix-entrypoint: $role needs Ray: use the render image (docker/Dockerfile.render)" >&2
      exit 2
    }
    # Options common to both; those left empty are Ray's defaults. The dashboard-agent port is
    # auto-assigned so that several nodes can share one host network (host networking, scaling).
    # RAY_NODE_IP: the address other nodes reach this one at (default: Ray detects it). Ray
    # replaces 127.0.0.1/localhost by the machine's outward address; for a one-machine cluster on
    # loopback use another 127.x address, e.g. 127.0.0.2 (docker/compose.yaml does).
    set -- --block --disable-usage-stats --dashboard-agent-listen-port 0 "$@"
    [ -n "${RAY_NODE_IP:-}" ] && set -- --node-ip-address "$RAY_NODE_IP" "$@"
    [ -n "${RAY_NUM_CPUS:-}" ] && set -- --num-cpus "$RAY_NUM_CPUS" "$@"
    [ -n "${RAY_OBJECT_STORE_MEMORY:-}" ] && set -- --object-store-memory "$RAY_OBJECT_STORE_MEMORY" "$@"
    if [ "$role" = ray-head ]; then
      exec ray start --head --port "${RAY_PORT:-6379}" --include-dashboard false "$@"
    fi
    exec ray start --address "${RAY_ADDRESS:?set RAY_ADDRESS to the head, e.g. 127.0.0.1:6379}" "$@"
    ;;
  *)
    exec "$role" "$@"
    ;;
esac
