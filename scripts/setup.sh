#!/usr/bin/env bash
# Installs what dynaorb needs on Debian 12, idempotently:
#  1. the apt packages of scripts/apt-packages.txt that are missing (none: no apt call);
#  2. .venv on Debian's /usr/bin/python3 with --system-site-packages (rospy,
#     cv_bridge and cv2 come from Debian), numpy pinned to Debian's;
#  3. the pip packages of requirements.txt and dynaorb itself (editable), redone
#     only when requirements.txt, pyproject.toml or setup.py change.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

mapfile -t packages < <(grep -v '^#' scripts/apt-packages.txt | tr ' ' '\n' | grep -v '^$')
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${#missing[@]} apt packages: ${missing[*]}"
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

if [ ! -x .venv/bin/python3 ]; then
  echo "setup: creating .venv on /usr/bin/python3"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
/usr/bin/python3 -c 'import numpy; print("numpy==" + numpy.__version__)' > constraints.txt

stamp=.venv/.dynaorb-pip-stamp
want=$(cat requirements.txt pyproject.toml setup.py constraints.txt | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing python packages into .venv"
  .venv/bin/pip install -q --disable-pip-version-check -c constraints.txt -r requirements.txt
  .venv/bin/pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$root"
  echo "$want" > "$stamp"
fi
