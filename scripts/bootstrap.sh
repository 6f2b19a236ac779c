#!/usr/bin/env bash
# Installs what pocketray needs on a fresh Debian machine. Idempotent and quick
# when nothing changed (a stamp of pyproject.toml's and the lock's hash skips pip).
#  - Mesa's EGL + llvmpipe for headless OpenGL (when libEGL is missing)
#  - Chromium for the browser tests, Node.js for the client's unit tests (node --test);
#    redis-server and haproxy for the scale-out stack (./dev stack and its test); kubectl
#    (Debian's kubernetes-client) for `kubectl kustomize`, which renders deploy/k8s in its test;
#    assimp-testmodels (assimp's model corpus, /usr/share/assimp/models) for the model-file test
#  - libLLVM 19 for Mitsuba 3's llvm variants (the peers and path experiments; Dr.Jit's
#    bundled LLVM 15 aborts in the path integrator, "Cannot select fminimum")
#  - a virtual environment .venv with the exact versions of requirements-test.lock (the
#    service and the test extras; scripts/lock.sh rewrites it), then the project itself
#    (editable, without resolving anything again)
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
ldconfig -p | grep -q 'libEGL.so.1' || need_apt+=(libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1)
ldconfig -p | grep -q 'libEGL_mesa' || need_apt+=(libegl-mesa0 libgl1-mesa-dri)
command -v chromium >/dev/null || need_apt+=(chromium)
command -v node >/dev/null || need_apt+=(nodejs)
command -v redis-server >/dev/null || need_apt+=(redis-server)
command -v haproxy >/dev/null || [ -x /usr/sbin/haproxy ] || need_apt+=(haproxy)
command -v kubectl >/dev/null || need_apt+=(kubernetes-client)
[ -d /usr/share/assimp/models ] || need_apt+=(assimp-testmodels)
ldconfig -p | grep -q 'libLLVM-19\|libLLVM.so.19' || [ -e /usr/lib/x86_64-linux-gnu/libLLVM-19.so ] || need_apt+=(libllvm19)
if [ ${#need_apt[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  echo "bootstrap: installing system packages: ${need_apt[*]}" >&2
  $SUDO apt-get update -q >/dev/null
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q "${need_apt[@]}" >/dev/null
fi

[ -x .venv/bin/python ] || python3 -m venv .venv
stamp=$(cat pyproject.toml requirements-test.lock | sha256sum | cut -c1-16)
if [ "$(cat .bootstrap-stamp 2>/dev/null || true)" != "$stamp" ]; then
  echo "bootstrap: installing Python packages into .venv (requirements-test.lock)" >&2
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null
  .venv/bin/python -m pip install -q -r requirements-test.lock
  # (setuptools' editable build warns about folders named like the packages: that is the layout)
  out=$(.venv/bin/python -m pip install -q --no-deps -e . 2>&1) || { echo "$out" >&2; exit 1; }
  echo "$stamp" > .bootstrap-stamp
fi
