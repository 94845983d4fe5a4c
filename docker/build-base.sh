#!/usr/bin/env bash
# Build a minimal Debian bookworm base image with Python 3.11 locally, for machines that reach
# Debian's package archive and PyPI but no container registry. It stands in for
# python:3.11-slim-bookworm: the images then build with
#   docker build --build-arg BASE=illumix-base:bookworm -f docker/Dockerfile.service .
#
# Usage (as root; needs debootstrap and a running Docker daemon):
#   bash docker/build-base.sh [--tag illumix-base:bookworm] [--mirror URL] [--force] [--no-host-ca]
#
# What is in it: debootstrap --variant=minbase of bookworm + python3, python3-venv, ca-certificates,
# with bookworm-updates / bookworm-security applied; apt lists, caches and docs (bar copyright
# files) removed. --no-host-ca: by default the CA certificates this host added locally
# (/usr/local/share/ca-certificates/*.crt, e.g. a TLS-intercepting egress proxy's) are trusted in
# the base too, so that pip and apt inside image builds work where the host's do; leave them out
# for a base that goes anywhere else.
set -euo pipefail

tag=illumix-base:bookworm
mirror=http://deb.debian.org/debian
security=http://deb.debian.org/debian-security
force=0
host_ca=1
while [ $# -gt 0 ]; do
  case "$1" in
    --tag) tag=$2; shift 2 ;;
    --mirror) mirror=$2; shift 2 ;;
    --security-mirror) security=$2; shift 2 ;;
    --force) force=1; shift ;;
    --no-host-ca) host_ca=0; shift ;;
    -h | --help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "build-base: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done

[ "$(id -u)" = 0 ] || { echo "build-base: run as root (debootstrap and chroot need it)" >&2; exit 2; }
command -v debootstrap >/dev/null || { echo "build-base: apt-get install -y debootstrap" >&2; exit 2; }
docker info >/dev/null 2>&1 || { echo "build-base: no Docker daemon answers (start dockerd)" >&2; exit 2; }
if [ "$force" = 0 ] && docker image inspect "$tag" >/dev/null 2>&1; then
  echo "build-base: $tag exists (--force rebuilds it)"
  exit 0
fi

root=$(mktemp -d /var/tmp/illumix-base.XXXXXX)
chmod 755 "$root"  # apt's _apt user must reach the chroot's partial-download directories
cleanup() {
  for m in proc dev/pts; do
    if mountpoint -q "$root/$m" 2>/dev/null; then umount -l "$root/$m" || true; fi
  done
  rm -rf --one-file-system "$root"
}
trap cleanup EXIT

echo "build-base: debootstrap bookworm from $mirror into $root"
debootstrap --variant=minbase --include=python3,python3-venv,ca-certificates \
  bookworm "$root" "$mirror" >/tmp/illumix-debootstrap.log 2>&1 \
  || { tail -20 /tmp/illumix-debootstrap.log >&2; exit 1; }

cat >"$root/etc/apt/sources.list" <<EOF
deb $mirror bookworm main
deb $mirror bookworm-updates main
deb $security bookworm-security main
EOF
# Like the official images: no recommends, no docs in later apt installs.
cat >"$root/etc/apt/apt.conf.d/90illumix" <<'EOF'
APT::Install-Recommends "false";
APT::Install-Suggests "false";
EOF
cat >"$root/etc/dpkg/dpkg.cfg.d/90illumix-nodoc" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
EOF

if [ "$host_ca" = 1 ] && compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
  echo "build-base: trusting this host's local CAs: $(cd /usr/local/share/ca-certificates && echo *.crt)"
  cp /usr/local/share/ca-certificates/*.crt "$root/usr/local/share/ca-certificates/"
fi

cp /etc/resolv.conf "$root/etc/resolv.conf"
mount -t proc proc "$root/proc"
mount --bind /dev/pts "$root/dev/pts"
chroot "$root" /bin/sh -euc '
  export DEBIAN_FRONTEND=noninteractive
  update-ca-certificates >/dev/null
  apt-get update -qq
  apt-get -y -qq upgrade >/dev/null
  apt-get clean
'
umount "$root/dev/pts" "$root/proc"
rm -f "$root/etc/resolv.conf"
# Shrink: package lists, caches, docs (copyright kept), man pages, logs, byte-code caches.
rm -rf "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/* "$root"/var/cache/debconf/*-old \
  "$root"/usr/share/man/* "$root"/usr/share/info/* "$root"/var/log/*.log "$root"/var/log/apt/*
find "$root/usr/share/doc" -mindepth 2 ! -name copyright -delete 2>/dev/null || true
find "$root/usr/share/locale" -mindepth 1 -maxdepth 1 ! -name locale.alias -exec rm -rf {} + 2>/dev/null || true
find "$root/usr/lib/python3"* -name __pycache__ -type d -prune -exec rm -rf {} + 2>/dev/null || true

py=$(chroot "$root" python3 -c 'import sys; print(".".join(map(str, sys.version_info[:3])))')
echo "build-base: importing as $tag (Python $py, $(du -sh "$root" | cut -f1))"
tar --numeric-owner -C "$root" -c . | docker import \
  --change 'ENV LANG=C.UTF-8' \
  --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
  --change 'CMD ["/bin/bash"]' \
  --change "LABEL org.opencontainers.image.description=\"Debian bookworm minbase + Python $py, built by illumix docker/build-base.sh\"" \
  - "$tag" >/dev/null
docker image ls "$tag"
