# The README's test command is `make test`; .ci/run calls exactly that.
PYTHON ?= python3

# Debian's ROS 1, for the live tests (tests/live): a real roscore, rospy nodes under
# /usr/bin/python3, roslaunch and rosbag record.
# python3-numba: the monitor's optional compiled checks (imrosc/runtime/compiled.py).
ROS1_DEBS := ros-core python3-rospy python3-std-msgs python3-geometry-msgs python3-sensor-msgs \
	python3-std-srvs python3-rosbag python3-numpy python3-yaml python3-numba
ROS1_IMPORTS := rospy, rosbag, roslaunch, numpy, yaml, numba, std_msgs.msg, geometry_msgs.msg, \
	sensor_msgs.msg, std_srvs.srv

# ROS 2 Jazzy, for the ROS 2 live tests (tests/backends/test_ros2*_live.py): a Python 3.11
# virtualenv outside the checkout with rclpy, rmw_fastrtps and message wheels from PyPI, numpy and
# numba (the monitor's compiled checks), colcon, and
# the launch system and `ros2` command from the vendored sources beside the checkout
# (tools/ros2_venv.sh), built once and reused while complete. The tests run with it and fail,
# rather than skip, when it is missing; `make test ROS2=no` leaves ROS 2 out (they are skipped).
ROS2 ?= yes
IMROSC_ROS2_VENV ?= $(HOME)/.cache/imrosc/ros2-jazzy
IMROSC_ROS2_VENDOR ?= $(CURDIR)/../shared/vendor/ros2-jazzy-launch
IMROSC_ROS2_BASE_PYTHON ?= $(PYTHON)
ifeq ($(ROS2),yes)
ROS2_ENV := IMROSC_ROS2_PYTHON="$(IMROSC_ROS2_VENV)/bin/python" IMROSC_REQUIRE_ROS2=1 \
	ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
endif

.PHONY: test install ros1 ros2 lint typecheck unit demo

test: install ros1 ros2 lint typecheck unit

install:
	$(PYTHON) -m pip install --quiet --disable-pip-version-check -e '.[test]'

# Installs ROS 1 only when it is missing, and only as root with apt-get (CI runs as root on
# a clean Debian machine); otherwise the live tests say why they are skipped.
ros1:
	@if [ -x /usr/bin/roscore ] && [ -x /usr/bin/python3 ] \
		&& /usr/bin/python3 -c 'import $(ROS1_IMPORTS)' >/dev/null 2>&1; then \
		:; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		echo "installing Debian's ROS 1 packages for the live tests"; \
		log=$$(mktemp); \
		if DEBIAN_FRONTEND=noninteractive apt-get update -q >"$$log" 2>&1 \
			&& DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
				$(ROS1_DEBS) >>"$$log" 2>&1; then \
			rm -f "$$log"; \
		else \
			cat "$$log"; rm -f "$$log"; exit 1; \
		fi; \
	else \
		echo "ROS 1 is missing and this is not root with apt-get: the live tests will be skipped"; \
	fi

ros2:
ifeq ($(ROS2),yes)
	@bash tools/ros2_venv.sh "$(IMROSC_ROS2_BASE_PYTHON)" "$(IMROSC_ROS2_VENV)" "$(IMROSC_ROS2_VENDOR)"
endif

lint:
	$(PYTHON) -m ruff check .
	$(PYTHON) -m ruff format --check .

typecheck:
	$(PYTHON) -m mypy

# ROS 2 logs go to a temporary folder, removed afterwards. PYTEST_ARGS: e.g. "-m live".
unit: ros2
	@logs=$$(mktemp -d); trap 'rm -rf "$$logs"' EXIT; set -x; \
	ROS_LOG_DIR="$$logs" $(ROS2_ENV) $(PYTHON) -m pytest $(PYTEST_ARGS)

demo:
	$(PYTHON) -m pip install --quiet --disable-pip-version-check . && imrosc demo
