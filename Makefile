# dynaorb: the two commands of the README, and their parts.
#   make demo   set up, build, run SLAM on the built-in synthetic dynamic sequence
#   make test   set up, build, run every test (gtest + rostest through ctest, then pytest)
SHELL := /bin/bash
ROOT := $(CURDIR)
BUILD := $(ROOT)/build
DEVEL := $(ROOT)/devel
VENV := $(ROOT)/.venv
PY := $(VENV)/bin/python3
JOBS ?= 2
export ROS_HOSTNAME ?= localhost
export ROS_HOME := $(BUILD)/ros_home
export ROS_LOG_DIR := $(BUILD)/ros_home/log
export MPLBACKEND := Agg
export PATH := $(VENV)/bin:$(PATH)

.PHONY: demo test setup build vocab clean

setup:
	@bash scripts/setup.sh

# The devel space (what `source devel/setup.bash` puts on the ROS paths) is
# kept out of build/: rosrun skips every file below PACKAGE/build/, so
# `rosrun dynaorb dynaorb_node` found nothing in build/devel.
$(BUILD)/CMakeCache.txt: | setup
	cmake -S $(ROOT) -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DPYTHON_EXECUTABLE=$(PY) -DCATKIN_DEVEL_PREFIX=$(DEVEL)

build: setup $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j$(JOBS)

# dynaorb's own bag-of-words vocabulary, trained on sequences it renders; cached
# in ~/.cache/dynaorb/vocab (about a minute the first time, nothing afterwards).
vocab: build
	$(PY) -m dynaorb vocab default

demo: vocab
	$(PY) -m dynaorb demo --out $(ROOT)/out/demo

test: vocab
	@mkdir -p $(ROS_LOG_DIR)
	cd $(BUILD) && ctest --output-on-failure -j$(JOBS)
	$(PY) -m pytest -q

clean:
	rm -rf $(BUILD) $(DEVEL)
