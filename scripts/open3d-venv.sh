# Sourced by the scripts that run Open3D beside us (never by the tests):
# installs Open3D into target/open3d-venv on first use (pip, ~1 min) and
# libusb (apt), which Open3D's import needs; sets $venv.
venv=target/open3d-venv
if [[ ! -x $venv/bin/python ]] || ! $venv/bin/python -c 'import open3d' 2>/dev/null; then
  if ! ldconfig -p | grep -q libusb-1.0; then
    apt-get install -y -q libusb-1.0-0 >/dev/null
  fi
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q open3d
fi
