#!/usr/bin/env bash
# End-to-end smoke test of the images on this machine (not part of CI: it builds images, minutes).
#
#   bash docker/smoke.sh [--no-build] [--keep]
#
# 1. builds the base (docker/build-base.sh, only when ILLUMIX_BASE is unset and illumix-base:bookworm
#    is missing), then illumix-service and illumix-render;
# 2. renders the demo room at 64x48, 16 spp into a fresh store volume with the render image;
# 3. starts a Ray head and one Ray worker from the render image and renders one tiny cube
#    (front/desk, 32x24) through the cluster, driven from the head (which has no CPUs: the worker
#    renders);
# 4. starts the service on the demo store and checks /health, one /sample (PNG and npz) and the
#    write token (an upload without it is refused, with it accepted);
# 5. removes the containers and the volume (--keep leaves them running; images are always kept).
#
# Everything uses host networking and binds 127.0.0.1 only. Environment: ILLUMIX_BASE (default: the
# local illumix-base:bookworm; e.g. python:3.11-slim-bookworm where a registry is reachable),
# ILLUMIX_TAG (dev), SMOKE_PORT (28000), SMOKE_RAY_PORT (26379; both outside
# Ray's worker-port range 10002-19999).
set -euo pipefail
cd "$(dirname "$0")/.."

build=1
keep=0
for a in "$@"; do
  case "$a" in
    --no-build) build=0 ;;
    --keep) keep=1 ;;
    -h | --help) sed -n '2,20p' "$0"; exit 0 ;;
    *) echo "smoke: unknown argument $a" >&2; exit 2 ;;
  esac
done

tag=${ILLUMIX_TAG:-dev}
svc_img=illumix-service:$tag
ren_img=illumix-render:$tag
port=${SMOKE_PORT:-28000}
ray_port=${SMOKE_RAY_PORT:-26379}
run_id=$$
vol=illumix-smoke-$run_id
head=illumix-smoke-head-$run_id
worker=illumix-smoke-worker-$run_id
svc=illumix-smoke-service-$run_id
token=smoke-token-$run_id
tmp=$(mktemp -d)
t_start=$(date +%s)

say() { printf 'smoke [%4ss] %s\n' "$(($(date +%s) - t_start))" "$*"; }
fail() {
  say "FAIL: $*"
  for c in "$svc" "$head" "$worker"; do
    docker ps -a --format '{{.Names}}' | grep -qx "$c" && { echo "--- logs $c"; docker logs --tail 30 "$c" 2>&1; }
  done
  exit 1
}
teardown() {
  rm -rf "$tmp"
  [ "$keep" = 1 ] && { say "--keep: left $svc $head $worker and volume $vol"; return; }
  docker rm -f "$svc" "$head" "$worker" >/dev/null 2>&1 || true
  docker volume rm "$vol" >/dev/null 2>&1 || true
  say "torn down (containers and volume removed)"
}
trap teardown EXIT

wait_healthy() {  # NAME SECONDS
  local s
  for _ in $(seq "$2"); do
    s=$(docker inspect -f '{{.State.Status}}/{{if .State.Health}}{{.State.Health.Status}}{{end}}' "$1" 2>/dev/null || echo gone)
    case "$s" in
      running/healthy) return 0 ;;
      exited/* | dead/* | gone) fail "$1 stopped ($s)" ;;
    esac
    sleep 1
  done
  fail "$1 not healthy after $2 s ($s)"
}

docker info >/dev/null 2>&1 || fail "no Docker daemon answers (start dockerd; see docker/README.md)"
say "docker: client $(docker version -f '{{.Client.Version}}' 2>/dev/null), server $(docker version -f '{{.Server.Version}}')"

# -- 1. images ----------------------------------------------------------------------------------
if [ "$build" = 1 ]; then
  base=${ILLUMIX_BASE:-illumix-base:bookworm}
  if [ -z "${ILLUMIX_BASE:-}" ] && ! docker image inspect "$base" >/dev/null 2>&1; then
    say "building the local base $base (docker/build-base.sh)"
    bash docker/build-base.sh --tag "$base"
  fi
  for pair in "service:$svc_img" "render:$ren_img"; do
    kind=${pair%%:*}
    img=${pair#*:}
    say "building $img (BASE=$base)"
    docker build -q --network host --build-arg BASE="$base" -f "docker/Dockerfile.$kind" -t "$img" . \
      >"$tmp/build-$kind.log" 2>&1 || { tail -30 "$tmp/build-$kind.log"; fail "docker build $img"; }
  done
fi
for img in "$svc_img" "$ren_img"; do
  docker image inspect "$img" >/dev/null 2>&1 || fail "image $img missing (run without --no-build)"
  say "image $img: $(docker image inspect -f '{{.Size}}' "$img" | awk '{printf "%.0f MB", $1/1e6}'), user $(docker image inspect -f '{{.Config.User}}' "$img")"
done
docker volume create "$vol" >/dev/null

# -- 2. demo store through the render image ------------------------------------------------------
say "rendering the demo room (64x48, 16 spp) with $ren_img"
docker run --rm --network host -v "$vol:/data" "$ren_img" \
  illumix render --demo --store /data/store --resolution 64x48 --spp 16 --json >"$tmp/render.json" \
  2>"$tmp/render.err" || { cat "$tmp/render.err"; fail "demo render"; }
python3 - "$tmp/render.json" <<'EOF' || fail "demo render summary"
import json, sys
s = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
cubes = [j for j in s["rendered"] if "[view" not in j]
assert len(cubes) == s["cubes_to_render"] > 0, s
print(f"smoke        rendered {len(cubes)} cubes + {len(s['rendered']) - len(cubes)} views in {s['seconds']:.1f} s")
EOF

# -- 3. one cube through a Ray head + worker --------------------------------------------------------
# Ray nodes on loopback: 127.0.0.2, since Ray replaces 127.0.0.1 by the machine's outward address.
ray_ip=127.0.0.2
say "starting Ray head ($ray_ip:$ray_port, 0 CPUs) and one worker"
docker run -d --name "$head" --network host --shm-size 512m --health-interval 2s -v "$vol:/data" \
  -e RAY_NODE_IP=$ray_ip -e RAY_PORT="$ray_port" -e RAY_ADDRESS="$ray_ip:$ray_port" -e RAY_NUM_CPUS=0 \
  "$ren_img" ray-head >/dev/null
wait_healthy "$head" 120
docker run -d --name "$worker" --network host --shm-size 512m --health-interval 2s -v "$vol:/data" \
  -e RAY_NODE_IP=$ray_ip -e RAY_ADDRESS="$ray_ip:$ray_port" "$ren_img" ray-worker >/dev/null
wait_healthy "$worker" 120
say "$(docker exec "$head" illumix-healthcheck)"
say "$(docker exec "$worker" illumix-healthcheck)"
nodes=0
for _ in $(seq 20); do  # the autoscaler's status lags node registration by a few seconds
  nodes=$(docker exec "$head" ray status 2>/dev/null | sed -n '/^Active:/,/^Pending:/p' | grep -c ' node_' || true)
  [ "$nodes" -ge 2 ] && break
  sleep 2
done
say "ray status: $nodes active nodes"
[ "$nodes" -ge 2 ] || fail "the worker did not join the head"
say "rendering front/desk (32x24, 16 spp) through Ray"
docker exec "$head" illumix render --demo --store /data/ray-store --resolution 32x24 --spp 16 \
  --views front --groups desk --executor ray --json >"$tmp/ray.json" 2>"$tmp/ray.err" \
  || { tail -20 "$tmp/ray.err"; fail "render through Ray"; }
python3 - "$tmp/ray.json" <<'EOF' || fail "Ray render summary"
import json, sys
s = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
assert "demo-room-0/front/desk" in s["rendered"], s
print(f"smoke        ray: rendered {', '.join(s['rendered'])} in {s['seconds']:.1f} s")
EOF
docker exec -e COLUMNS=110 "$head" illumix store info /data/ray-store 2>&1 | sed 's/^/smoke        /' | head -12 || true

# -- 4. the service ---------------------------------------------------------------------------------
say "starting the service on 127.0.0.1:$port over the demo store"
docker run -d --name "$svc" --network host --health-interval 2s -v "$vol:/data" \
  -e ILLUMIX_PORT="$port" -e ILLUMIX_TOKEN="$token" -e ILLUMIX_CACHE_MB=64 "$svc_img" >/dev/null
wait_healthy "$svc" 90
base_url=http://127.0.0.1:$port
say "GET /health -> $(curl -fsS "$base_url/health")"
code=$(curl -sS -o "$tmp/s.png" -w '%{http_code} %{content_type} %{size_download}' \
  "$base_url/sample?pair=A,D65&sensor=XYZ&outputs=srgb&format=png")
say "GET /sample?pair=A,D65&sensor=XYZ&outputs=srgb&format=png -> $code"
if [ "${code%% *}" != 200 ] || [ "$(head -c 4 "$tmp/s.png" | tail -c 3)" != PNG ]; then fail "/sample png"; fi
code=$(curl -sS -o "$tmp/s.npz" -w '%{http_code} %{content_type} %{size_download}' \
  "$base_url/sample?pair=FL2,D65&sensor=XYZ")
say "GET /sample?pair=FL2,D65&sensor=XYZ (npz) -> $code"
[ "${code%% *}" = 200 ] || fail "/sample npz"
python3 - "$tmp/s.npz" <<'EOF' || fail "npz content"
import sys, zipfile
names = zipfile.ZipFile(sys.argv[1]).namelist()
assert names, "empty npz"
print("smoke        npz arrays:", ", ".join(n.removesuffix(".npy") for n in names))
EOF
awk 'BEGIN { for (w = 380; w <= 780; w += 5) printf "%d,1.0\n", w }' >"$tmp/flat.csv"
code=$(curl -sS -o /dev/null -w '%{http_code}' -F name=smoke-flat -F "file=@$tmp/flat.csv" "$base_url/illuminants")
say "POST /illuminants without token -> $code"
[ "$code" = 401 ] || fail "upload without token was not refused"
code=$(curl -sS -o /dev/null -w '%{http_code}' -H "Authorization: Bearer $token" \
  -F name=smoke-flat -F "file=@$tmp/flat.csv" "$base_url/illuminants")
say "POST /illuminants with token -> $code"
[ "$code" = 201 ] || fail "upload with token"
say "service log tail:"
docker logs --tail 4 "$svc" 2>&1 | sed 's/^/smoke        /'
say "OK: images build, render locally and through Ray, serve /health and /sample, enforce the token"
