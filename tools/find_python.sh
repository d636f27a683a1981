#!/usr/bin/env sh
# Print the path of a working CPython X.Y interpreter with venv, or explain on stderr and fail.
#   tools/find_python.sh 3.13
# Looks, in order, at: $PYTHON_X_Y (e.g. PYTHON_3_13) if set, pythonX.Y on PATH, pyenv's
# versions (~/.pyenv/versions/X.Y*/bin, or $PYENV_ROOT's), /usr/local/bin and /usr/bin.
# A pyenv shim on PATH that does not run because another version is selected is skipped.
set -u
version="${1:?usage: find_python.sh X.Y}"
override_var="PYTHON_$(echo "$version" | tr . _)"
eval "override=\${$override_var:-}"

works() {
  [ -n "$1" ] && [ -x "$1" ] && "$1" -c "import sys, venv, ensurepip
sys.exit(sys.version_info[:2] != tuple(map(int, '$version'.split('.'))))" >/dev/null 2>&1
}

if [ -n "$override" ]; then
  if works "$override"; then echo "$override"; exit 0; fi
  echo "error: $override_var=$override is not a working Python $version with venv" >&2
  exit 1
fi
pyenv_root="${PYENV_ROOT:-$HOME/.pyenv}"
for candidate in "$(command -v "python$version" 2>/dev/null)" \
                 $(ls -d "$pyenv_root"/versions/"$version"*/bin/python"$version" 2>/dev/null \
                   | sort -V -r) \
                 "/usr/local/bin/python$version" "/usr/bin/python$version"; do
  if works "$candidate"; then echo "$candidate"; exit 0; fi
done
cat >&2 <<MSG
error: no working Python $version found (with the venv module): looked for python$version on PATH,
  in $pyenv_root/versions/$version*/bin, /usr/local/bin and /usr/bin.
  Install it, e.g. 'pyenv install $version', or 'apt-get install python$version python$version-venv'
  where apt has it (Debian 13, Ubuntu 25.04), or name one with $override_var=/path/to/python$version.
MSG
exit 1
