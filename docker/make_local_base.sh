#!/usr/bin/env bash
# A local stand-in for python:3.11.7-slim-bookworm, for machines that reach a Debian mirror but
# not Docker Hub: a minimal Debian 12 from the mirror, its python3 (3.11) in a venv on PATH so
# that `python` and `pip` work as in the official image (and pip installs into the venv, not
# into Debian's Python), committed as a local image to pass as `--build-arg BASE=`.
#   sudo docker/make_local_base.sh DEBIAN_MIRROR_URL [IMAGE]   (needs buildah and debootstrap)
set -euo pipefail

mirror=${1:?usage: $0 DEBIAN_MIRROR_URL [IMAGE]}
image=${2:-localhost/bookworm-python:3.11}

container=$(buildah from scratch)
trap 'buildah rm "$container" >/dev/null' EXIT
root=$(buildah mount "$container")

debootstrap --variant=minbase --include=python3,python3-venv,ca-certificates bookworm "$root" "$mirror"
# The certificate authorities this host adds to Debian's (a TLS-intercepting egress proxy, say):
# pip in the build reaches PyPI as this host does (Debian's pip trusts the system store).
find /usr/local/share/ca-certificates -name '*.crt' -exec cp -t "$root/usr/local/share/ca-certificates/" {} +
chroot "$root" update-ca-certificates
chroot "$root" python3 -m venv /opt/venv
chroot "$root" apt-get clean
rm -rf "$root"/var/lib/apt/lists/* "$root"/var/log/*.log "$root"/var/cache/debconf/*-old

buildah umount "$container" >/dev/null
buildah config \
    --env PATH=/opt/venv/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
    --env LANG=C.UTF-8 \
    --cmd python \
    "$container"
buildah commit --rm "$container" "$image"
trap - EXIT
