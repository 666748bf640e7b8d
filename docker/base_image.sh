# shellcheck shell=bash
# Sourced by scripts/docker_check.sh: make sure a base image with Python 3.11 exists.
# Uses $BASE_IMAGE when it is present or can be pulled; otherwise builds one from Debian's
# packages (debootstrap minbase + python3, python3-venv, ca-certificates) and `docker import`s
# it, so no image registry is needed. The result is kept in the engine's data root (cache).
WMB_LOCAL_BASE="${WMB_LOCAL_BASE:-wmb-base:bookworm-py3.11}"
DEBIAN_MIRROR="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"

_rootfs_remove() {   # debootstrap mounts proc and sys inside; never delete through a mount
  local m
  for m in $(findmnt -rn -o TARGET | grep -F "$1/" | sort -r); do umount -l "$m" || true; done
  rm -rf --one-file-system "$1"
}

base_image() {   # prints the tag to build FROM
  local want="${BASE_IMAGE:-python:3.11-slim}"
  if "$DOCKER" image inspect "$want" >/dev/null 2>&1; then echo "$want"; return 0; fi
  if [ -z "${BASE_IMAGE:-}" ] && "$DOCKER" image inspect "$WMB_LOCAL_BASE" >/dev/null 2>&1; then
    echo "$WMB_LOCAL_BASE"; return 0
  fi
  echo "docker-check: pulling $want" >&2
  if timeout 60 "$DOCKER" pull -q "$want" >/dev/null 2>&1; then echo "$want"; return 0; fi
  if [ -n "${BASE_IMAGE:-}" ]; then
    echo "docker-check: BASE_IMAGE=$BASE_IMAGE is neither present nor pullable" >&2; return 2
  fi
  echo "docker-check: $want cannot be pulled; building $WMB_LOCAL_BASE with debootstrap" >&2
  local root
  root="$(mktemp -d /var/tmp/wmb-rootfs.XXXXXX)"
  if ! debootstrap --variant=minbase --include=python3,python3-venv,ca-certificates \
      bookworm "$root" "$DEBIAN_MIRROR" >"$root.log" 2>&1; then
    echo "docker-check: debootstrap failed; the end of $root.log:" >&2; tail -5 "$root.log" >&2
    _rootfs_remove "$root"; return 1
  fi
  rm -rf "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/* "$root"/usr/share/doc/* \
    "$root"/usr/share/man/* "$root"/usr/share/locale/*
  tar -C "$root" -c . | "$DOCKER" import -c 'ENV LANG=C.UTF-8' -c 'CMD ["python3"]' - "$WMB_LOCAL_BASE" >/dev/null
  _rootfs_remove "$root"; rm -f "$root.log"
  echo "$WMB_LOCAL_BASE"
}
