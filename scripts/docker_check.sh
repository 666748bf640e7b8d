#!/usr/bin/env bash
# make docker-check: build the reproduction image on this machine and check it end to end.
# Installs Debian's docker.io and debootstrap when missing, runs a private dockerd (own data
# root, no iptables, no bridge; stopped at the end, also on failure), makes a base image from
# Debian's packages when BASE_IMAGE cannot be pulled, builds the image (--network host; the
# torch wheel pip finds here, pip's CA bundle as a build secret), runs the smoke grid and
# `report` in a container without network as a non-root --user, and checks that the
# container's train and eval rows equal a host run of the same grid bit for bit.
# HOST_RUN=DIR reuses a host smoke run (CI passes its own); otherwise one is made.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
IMAGE="${IMAGE:-warehouse-marl-bench:check}"
OUT=results/docker-check
CHECK_UID="${CHECK_UID:-4321}"   # a uid that exists in no image: --user must work with any
# shellcheck source=../docker/engine.sh
source docker/engine.sh
# shellcheck source=../docker/base_image.sh
source docker/base_image.sh
step() { echo "docker-check: $* ($(( $(date +%s) - start )) s)"; }

engine_install
trap engine_stop EXIT
engine_start
step "dockerd $("$DOCKER" version -f '{{.Server.Version}}') up, data root $WMB_DOCKER_ROOT"
base="$(base_image)"
step "base image $base"

# torch: the wheel pip would install here (pip's find-links), hard-linked into the context
rm -f docker/wheels/*.whl
for dir in $(.venv/bin/pip config get global.find-links 2>/dev/null || true) ${PIP_FIND_LINKS:-}; do
  for whl in "$dir"/torch-2.13.0*-cp311-*.whl; do
    [ -f "$whl" ] && { ln -f "$whl" docker/wheels/ 2>/dev/null || cp "$whl" docker/wheels/; }
  done
done
secret=()
ca="$(.venv/bin/pip config get global.cert 2>/dev/null || echo "${PIP_CERT:-}")"
[ -n "$ca" ] && [ -f "$ca" ] && secret=(--secret "id=pip_ca,src=$ca")
b0=$(date +%s)
DOCKER_BUILDKIT=1 "$DOCKER" build --network host --progress plain \
  --build-arg "BASE_IMAGE=$base" "${secret[@]}" -t "$IMAGE" . >"$WMB_DOCKER_RUN/build.log" 2>&1 \
  || { tail -30 "$WMB_DOCKER_RUN/build.log" >&2; echo "docker-check: build failed" >&2; exit 1; }
rm -f docker/wheels/*.whl
size=$("$DOCKER" image inspect -f '{{.Size}}' "$IMAGE")
step "image $IMAGE built in $(( $(date +%s) - b0 )) s, $(( size / 1000000 )) MB"
# the CA must not be in the image, nor dev tools or tests
if "$DOCKER" run --rm --network none --entrypoint sh "$IMAGE" -c \
    'ls /run/secrets/pip_ca /opt/venv/bin/pytest /opt/venv/bin/ruff 2>/dev/null; ls -d /tests /app/tests 2>/dev/null' | grep .; then
  echo "docker-check: the image holds files it must not (above)" >&2; exit 1
fi

host="${HOST_RUN:-}"
if [ -z "$host" ]; then
  host="$OUT/host"
  rm -rf "$host"
  .venv/bin/bench run --grid smoke --out "$host" >"$WMB_DOCKER_RUN/host-run.log" 2>&1 \
    || { tail -20 "$WMB_DOCKER_RUN/host-run.log" >&2; exit 1; }
  step "host smoke run in $host"
fi

rm -rf "$OUT/container"
mkdir -p "$OUT/container"
chown "$CHECK_UID:$CHECK_UID" "$OUT/container"
r0=$(date +%s)
run=("$DOCKER" run --rm --network none --shm-size=2g --user "$CHECK_UID:$CHECK_UID" -v "$PWD/$OUT/container:/results" "$IMAGE")
"${run[@]}" run --grid smoke --out /results/smoke >"$WMB_DOCKER_RUN/container-run.log" 2>&1 \
  || { tail -20 "$WMB_DOCKER_RUN/container-run.log" >&2; echo "docker-check: smoke in the container failed" >&2; exit 1; }
r1=$(date +%s)
"${run[@]}" report --run /results/smoke >"$WMB_DOCKER_RUN/container-report.log" 2>&1 \
  || { tail -20 "$WMB_DOCKER_RUN/container-report.log" >&2; echo "docker-check: report in the container failed" >&2; exit 1; }
step "container: smoke grid $(( r1 - r0 )) s, report $(( $(date +%s) - r1 )) s"
[ -s "$OUT/container/smoke/report/index.html" ] || { echo "docker-check: no report/index.html from the container" >&2; exit 1; }
owner=$(stat -c %u:%g "$OUT/container/smoke/cells.parquet")
[ "$owner" = "$CHECK_UID:$CHECK_UID" ] || { echo "docker-check: results owned by $owner, not --user $CHECK_UID:$CHECK_UID" >&2; exit 1; }

.venv/bin/python scripts/compare_runs.py "$host" "$OUT/container/smoke" --names host container
step "passed; image $(( size / 1000000 )) MB"
