# shellcheck shell=bash
# Sourced by scripts/docker_check.sh: a private Docker engine for the check.
# Installs Debian's docker.io (and debootstrap) when missing, starts dockerd with its own data
# root and socket, no iptables and no bridge, and stops it again from an EXIT trap.
WMB_DOCKER_ROOT="${WMB_DOCKER_ROOT:-/var/lib/wmb-docker}"   # images and build cache persist here
WMB_DOCKER_RUN="${WMB_DOCKER_RUN:-/run/wmb-docker}"
export DOCKER_HOST="unix://$WMB_DOCKER_RUN/docker.sock"
DOCKER=/usr/bin/docker    # Debian's CLI (BuildKit built in); a newer CLI elsewhere on PATH wants buildx

engine_install() {
  local missing=()
  [ -x /usr/sbin/dockerd ] && [ -x "$DOCKER" ] || missing+=(docker.io)
  command -v debootstrap >/dev/null || missing+=(debootstrap)
  [ ${#missing[@]} -eq 0 ] && return 0
  [ "$(id -u)" = 0 ] || { echo "docker-check: needs root to install ${missing[*]}" >&2; return 2; }
  echo "docker-check: installing ${missing[*]} from Debian"
  export DEBIAN_FRONTEND=noninteractive
  apt-get -o DPkg::Lock::Timeout=900 update -q >/dev/null
  apt-get -o DPkg::Lock::Timeout=900 install -y -q --no-install-recommends "${missing[@]}" >/dev/null
}

engine_start() {
  mkdir -p "$WMB_DOCKER_ROOT" "$WMB_DOCKER_RUN"
  if [ -f "$WMB_DOCKER_RUN/dockerd.pid" ] && kill -0 "$(cat "$WMB_DOCKER_RUN/dockerd.pid")" 2>/dev/null; then
    echo "docker-check: a dockerd of an earlier check still runs (pid $(cat "$WMB_DOCKER_RUN/dockerd.pid")); stop it first" >&2
    return 2
  fi
  /usr/sbin/dockerd --data-root "$WMB_DOCKER_ROOT" --exec-root "$WMB_DOCKER_RUN/exec" \
    --host "$DOCKER_HOST" --pidfile "$WMB_DOCKER_RUN/dockerd.pid" \
    --iptables=false --ip6tables=false --bridge=none \
    --containerd-namespace wmb --containerd-plugins-namespace wmb-plugins \
    >"$WMB_DOCKER_RUN/dockerd.log" 2>&1 &
  WMB_DOCKERD_PID=$!
  for _ in $(seq 60); do
    "$DOCKER" version >/dev/null 2>&1 && return 0
    kill -0 "$WMB_DOCKERD_PID" 2>/dev/null || break
    sleep 1
  done
  echo "docker-check: dockerd did not start; its log:" >&2
  tail -20 "$WMB_DOCKER_RUN/dockerd.log" >&2
  return 1
}

engine_stop() {
  [ -n "${WMB_DOCKERD_PID:-}" ] || return 0
  kill "$WMB_DOCKERD_PID" 2>/dev/null || true
  for _ in $(seq 30); do kill -0 "$WMB_DOCKERD_PID" 2>/dev/null || break; sleep 1; done
  kill -9 "$WMB_DOCKERD_PID" 2>/dev/null || true
  # its managed containerd (a child in the same exec root) goes with it; one left over is ours
  local cpid="$WMB_DOCKER_RUN/exec/containerd/containerd.pid"
  [ -f "$WMB_DOCKER_RUN/containerd.pid" ] && cpid="$WMB_DOCKER_RUN/containerd.pid"
  if [ -f "$cpid" ] && kill -0 "$(cat "$cpid")" 2>/dev/null; then kill "$(cat "$cpid")" 2>/dev/null || true; fi
  WMB_DOCKERD_PID=
  echo "docker-check: dockerd stopped"
}
