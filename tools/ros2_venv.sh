#!/usr/bin/env bash
# Creates (or reuses) the ROS 2 Jazzy virtualenv of the ROS 2 live tests, outside the checkout:
# rclpy, rmw_fastrtps and the message packages (wheels from PyPI), numpy and numba (the monitor's
# compiled checks, imrosc/runtime/compiled.py), colcon (PyPI), and the launch
# system and `ros2` command from their vendored pure-Python sources, with a stand-in for the
# `composition_interfaces` message package (not published as a wheel; see the vendor README).
#
# usage: tools/ros2_venv.sh PYTHON VENV VENDOR
#   PYTHON  the interpreter that creates the virtualenv (Python 3.11: the wheels' C extensions)
#   VENV    where the virtualenv lives (make: IMROSC_ROS2_VENV, default ~/.cache/imrosc/ros2-jazzy)
#   VENDOR  the vendored sources (make: IMROSC_ROS2_VENDOR, default ../shared/vendor/ros2-jazzy-launch)
#
# A complete virtualenv holds a marker with this script's and the vendor README's checksums; when
# it matches, nothing is done. Otherwise the virtualenv is built again from scratch (a lock keeps
# two runs from building it at once) and the marker is written last.
set -euo pipefail

python=$1
venv=$2
vendor=$3
marker="$venv/.imrosc-ros2-complete"

[ -f "$vendor/README.md" ] || {
	echo "ROS 2: no vendored launch sources at $vendor (set IMROSC_ROS2_VENDOR)" >&2
	exit 1
}
stamp=$(cat "$0" "$vendor/README.md" | sha256sum | cut -c1-16)
complete() { [ -x "$venv/bin/python" ] && [ "$(cat "$marker" 2>/dev/null)" = "$stamp" ]; }
complete && exit 0

mkdir -p "$(dirname "$venv")"
exec 9>"$venv.lock"
flock 9
complete && exit 0 # built by another run while this one waited

echo "ROS 2: creating the Jazzy virtualenv of the live tests in $venv"
started=$(date +%s)
log=$(mktemp)
work=$(mktemp -d)
trap 'rm -rf "$work" "$log"' EXIT
fail() {
	cat "$log" >&2
	echo "ROS 2: $1 failed; see above" >&2
	rm -rf "$venv"
	exit 1
}
pip() { "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$@" >>"$log" 2>&1; }

rm -rf "$venv"
version=$("$python" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
[ "$version" = 3.11 ] || {
	echo "ROS 2: the Jazzy wheels are built for Python 3.11, $python is $version" \
		"(set IMROSC_ROS2_BASE_PYTHON)" >&2
	exit 1
}
# without ensurepip (Debian without python3-venv), the creating python's pip bootstraps pip
"$python" -m venv "$venv" >>"$log" 2>&1 || {
	rm -rf "$venv"
	"$python" -m venv --without-pip "$venv" >>"$log" 2>&1 &&
		"$python" -m pip --python "$venv/bin/python" install --quiet pip >>"$log" 2>&1
} || fail "python -m venv"
pip --upgrade pip setuptools wheel || fail "pip install pip"
pip "ros-jazzy-rclpy[fastrtps]" ros-jazzy-std-msgs ros-jazzy-std-srvs ros-jazzy-sensor-msgs \
	ros-jazzy-geometry-msgs ros-jazzy-rcl-interfaces ros-jazzy-builtin-interfaces \
	ros-jazzy-lifecycle-msgs ros-jazzy-ament-index-python numpy numba \
	colcon-core colcon-python-setup-py colcon-ros \
	osrf-pycommon psutil packaging pyyaml lark catkin-pkg importlib-metadata ||
	fail "pip install (rclpy, messages, numba, colcon)"

# the vendored sources are read-only material: build from a copy (pip writes build/ beside them)
for folder in launch launch_xml launch_yaml launch_ros ros2cli ros2pkg ros2run ros2launch; do
	cp -r "$vendor/$folder" "$work/$folder"
	rm -rf "$work/$folder/build" "$work/$folder"/*.egg-info
done
(cd "$work" && pip --no-deps --no-build-isolation ./launch ./launch_xml ./launch_yaml \
	./launch_ros ./ros2cli ./ros2pkg ./ros2run ./ros2launch) || fail "pip install (launch, ros2cli)"

site=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
mkdir -p "$site/composition_interfaces"
cat >"$site/composition_interfaces/__init__.py" <<'EOF'
"""Stand-in for ROS 2's composition_interfaces (imrosc's ROS 2 test virtualenv).

launch_ros imports it at import time; the message package is not published as a wheel. The
generated launch files start no composable nodes, so loading one fails here, loudly.
"""
EOF
cat >"$site/composition_interfaces/srv.py" <<'EOF'
"""Stand-in service types: they can be named, and fail when used (see the package)."""


class _Missing:
    def __init__(self, *args, **kwargs):
        raise RuntimeError(
            "composable nodes are not available here: composition_interfaces is a stand-in"
        )


class LoadNode:
    Request = Response = _Missing


class UnloadNode:
    Request = Response = _Missing


class ListNodes:
    Request = Response = _Missing
EOF

"$venv/bin/python" -c 'import rclpy, numpy, numba, std_srvs.srv, sensor_msgs.msg, geometry_msgs.msg
import rcl_interfaces.srv, service_msgs.msg, lifecycle_msgs.msg, launch, launch_ros, launch_xml, ros2launch
import colcon_core, colcon_ros' >>"$log" 2>&1 || fail "the import check"
[ -x "$venv/bin/ros2" ] && [ -x "$venv/bin/colcon" ] || fail "the ros2 and colcon commands"
echo "$stamp" >"$marker"
echo "ROS 2: the virtualenv is ready ($(($(date +%s) - started)) s)"
