#!/usr/bin/env bash
# Rewrites the lock files from pyproject.toml's ranges (uv pip compile, universal markers):
#   requirements.lock       the service (what the wheel needs; the Docker image installs it)
#   requirements-test.lock  the service + the test extras (what scripts/bootstrap.sh installs)
#
#   scripts/lock.sh                  keep every version .venv has now (add only what is new)
#   scripts/lock.sh --upgrade        the newest releases pyproject.toml allows
#   scripts/lock.sh --upgrade-package NAME   one package newer, the rest kept
# Then run ./dev test (bootstrap re-installs when a lock changed) and commit the locks.
# uv itself is installed into a throw-away directory from PyPI, not into .venv.
set -euo pipefail
cd "$(dirname "$0")/.."
tool=$(mktemp -d)
trap 'rm -rf "$tool"' EXIT
.venv/bin/python -m pip install -q --target "$tool" uv >/dev/null
uv="$tool/bin/uv"
args=(--universal --python-version 3.11 --quiet)
mode="${1:-}"
if [ "$mode" = "--upgrade" ]; then
  args+=(--upgrade)
elif [ "$mode" = "--upgrade-package" ]; then
  args+=(--upgrade-package "$2")
fi
if [ "$mode" != "--upgrade" ]; then
  # Keep what .venv has: its versions are the preferences (constraints) of the resolution.
  .venv/bin/python -m pip freeze --exclude-editable | grep -v '^pocketray' > "$tool/keep.txt"
  [ "$mode" = "--upgrade-package" ] && sed -i "/^$2==/Id" "$tool/keep.txt"
  args+=(-c "$tool/keep.txt")
fi
for target in requirements.lock requirements-test.lock; do
  extra=(); [ "$target" = requirements-test.lock ] && extra=(--extra test)
  "$uv" pip compile pyproject.toml "${extra[@]}" "${args[@]}" --no-annotate \
    --custom-compile-command "scripts/lock.sh" -o "$target"
done
echo "lock: wrote requirements.lock ($(grep -c '==' requirements.lock) pins) and requirements-test.lock ($(grep -c '==' requirements-test.lock) pins)"
