#!/usr/bin/env bash
# OpenBLAS's serial build (Debian's libopenblas0-serial, built without locking) gives wrong
# results when OpenCV calls it from several threads at once, as odocal's tests and arena
# tracking do. Where it is the selected BLAS or LAPACK, select Debian's reference ones
# (libblas3, liblapack3, which `make deps` installs) instead.
set -euo pipefail
arch="$(uname -m)-linux-gnu"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
for pair in blas:libblas.so.3 lapack:liblapack.so.3; do
  dir="${pair%%:*}" lib="${pair#*:}"
  name="$lib-$arch"
  current="$(update-alternatives --query "$name" 2>/dev/null | sed -n 's/^Value: //p' || true)"
  case "$current" in
    */openblas-serial/*)
      echo "selecting Debian's reference $lib over OpenBLAS's serial build (not thread-safe)"
      $sudo update-alternatives --set "$name" "/usr/lib/$arch/$dir/$lib"
      ;;
  esac
done
