# The README's test command is `make test`; .ci/run calls exactly that.
PYTHON ?= python3

# Debian's ROS 1, for the live tests (tests/live): a real roscore, rospy nodes under
# /usr/bin/python3, roslaunch and rosbag record.
# python3-numba: the monitor's optional compiled checks (imrosc/runtime/compiled.py).
ROS1_DEBS := ros-core python3-rospy python3-std-msgs python3-geometry-msgs python3-sensor-msgs \
	python3-std-srvs python3-rosbag python3-numpy python3-yaml python3-numba
ROS1_IMPORTS := rospy, rosbag, roslaunch, numpy, yaml, numba, std_msgs.msg, geometry_msgs.msg, \
	sensor_msgs.msg, std_srvs.srv

.PHONY: test install ros1 lint typecheck unit demo

test: install ros1 lint typecheck unit

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

lint:
	$(PYTHON) -m ruff check .
	$(PYTHON) -m ruff format --check .

typecheck:
	$(PYTHON) -m mypy

unit:
	$(PYTHON) -m pytest

demo:
	$(PYTHON) -m pip install --quiet --disable-pip-version-check . && imrosc demo
