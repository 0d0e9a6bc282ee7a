# Felt: `make run` and `make test` do all set-up on a fresh Debian machine (see README.md).
SHELL := /bin/bash
.DEFAULT_GOAL := run

# Debian packages the build, tests and plots need. libbullet-dev: Bullet's btSoftBody, the peer
# of `felt bench cloth --tradeoff` only (Felt's libraries never link it; without it the bench skips
# its Bullet rows). nodejs (and npm, see npm-deps): the independent MCAP and ROS 2 CDR checkers of
# the tests (tools/npm). openssl: `felt security init` (DDS Security identities) and its tests.
# libcivetweb-dev: the live view's HTTP and WebSocket server; libjs-three: three.js r111, which the
# view serves (docs/view.md); chromium and libpng-dev: the view's browser test (headless
# screenshots, decoded in the test).
PACKAGES := cmake ninja-build g++ gcc make pkg-config libeigen3-dev cyclonedds-dev \
            cyclonedds-tools libddsc0debian libspdlog-dev libcli11-dev libtomlplusplus-dev \
            libgtest-dev googletest gnuplot-nox nlohmann-json3-dev libbullet-dev nodejs openssl \
            libcivetweb-dev libjs-three libpng-dev chromium
JOBS ?= $(shell nproc)
BUILD ?= build
CMAKE_FLAGS ?=
# In CI each test build's objects, static libraries and precompiled headers are deleted once its
# tests pass (PRUNE), so that the three builds never hold about 3 GB of disk at once (a CI run
# once stopped with "No space left on device" in the ASan build); the executables stay.
PRUNE = @true
ifeq ($(CI),true)
  CMAKE_FLAGS += -DFELT_WERROR=ON
  PRUNE = find $(1) -type f \( -name '*.o' -o -name '*.a' -o -name '*.gch' \) -delete
endif
SCENE ?= scenes/curtain.toml
# The live view of `make run` (issue 25): its port on 127.0.0.1; empty for none.
VIEW_PORT ?= 8080

.PHONY: deps npm-deps build run test test-release test-asan test-tsan bench clean

# Install missing packages as root; otherwise print the exact apt-get line and stop.
deps:
	@missing=$$(for p in $(PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'install ok installed' || echo $$p; \
	done | tr '\n' ' '); \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ]; then \
	    echo "Installing missing packages: $$missing"; \
	    DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	  else \
	    echo "Missing Debian packages. Run as root:"; \
	    echo "  apt-get install -y $$missing"; exit 1; \
	  fi; \
	fi

# The tests' independent checkers (@mcap/core, @foxglove/rosmsg2-serialization; versions pinned
# by tools/npm/package-lock.json) into tools/npm/node_modules, never at CMake configure time.
# When the registry cannot be reached this says so and goes on: the tests that need them skip
# and say why. Debian's npm package is installed here only when no `npm` command exists: it
# conflicts with a nodejs that bundles npm (NodeSource's), where it would break `make deps`.
npm-deps: deps
	@if [ -d tools/npm/node_modules/@mcap/core ] && \
	    [ -d tools/npm/node_modules/@foxglove/rosmsg2-serialization ]; then exit 0; fi; \
	if ! command -v npm > /dev/null && [ "$$(id -u)" = 0 ]; then \
	  echo "npm-deps: installing Debian's npm"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends npm || true; \
	fi; \
	if ! command -v npm > /dev/null; then \
	  echo "npm-deps: npm is not installed (apt-get install -y npm): the MCAP/CDR independent" \
	       "checks will be skipped"; \
	elif (cd tools/npm && timeout 300 npm ci --no-audit --no-fund --loglevel=error); then \
	  echo "npm-deps: installed tools/npm/node_modules"; \
	else \
	  echo "npm-deps: npm ci failed (registry unreachable?): the MCAP/CDR independent checks will be skipped"; \
	fi

$(BUILD)/build.ninja: CMakeLists.txt | deps
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release -DFELT_TEST_MODULES= $(CMAKE_FLAGS)

build: deps $(BUILD)/build.ninja
	cmake --build $(BUILD) -j $(JOBS)

# The demo: the server and a replay of a bundled trace over loopback DDS for about ten seconds,
# then a short summary (docs/replay.md). Thresholds are reported, not enforced (--report-only).
# make run serves the live 3-D view (docs/view.md) on VIEW_PORT during the run (VIEW_PORT= for none).
run: build
	@$(if $(VIEW_PORT),echo "make run: watch it live at http://127.0.0.1:$(VIEW_PORT)/ (VIEW_PORT=N for another port, VIEW_PORT= for none)",echo "make run: no live view (VIEW_PORT is empty)")
	@echo "          (a trace at your own pace: ./$(BUILD)/felt view --scene $(SCENE) --trace recordings/poke_hold.trace --port 8080)"
	./$(BUILD)/felt soak --minutes 0.17 --scene $(SCENE) --trace recordings/poke_hold.trace \
	  --report-only $(if $(VIEW_PORT),--view $(VIEW_PORT))

# Every test: the release build, then ASan+UBSan on everything, then TSan on threaded code.
test: deps npm-deps test-release test-asan test-tsan
	@echo "make test: all test builds passed ($$(date -u +%H:%M:%S))"

test-release: deps npm-deps
	@echo "== make test-release: start $$(date -u +%H:%M:%S)"
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release -DFELT_TEST_MODULES= $(CMAKE_FLAGS)
	cmake --build $(BUILD) -j $(JOBS)
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)
	$(call PRUNE,$(BUILD))

# Sanitizer builds: -O1 with line tables only (enough for stack traces), and unity batches of 16
# files (each heavy header's inline code instrumented once per batch), to keep CI's three builds on
# two cores inside its time budget (the lighter tests at -O0: CMakeLists.txt, FELT_SAN_GLUE_OPT).
SAN_FLAGS := -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" \
             "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DFELT_UNITY_BATCH=16

test-asan: deps
	@echo "== make test-asan: start $$(date -u +%H:%M:%S)"
	cmake -S . -B $(BUILD)-asan -G Ninja $(SAN_FLAGS) -DFELT_SANITIZE=address -DFELT_TEST_MODULES= \
	  $(CMAKE_FLAGS)
	cmake --build $(BUILD)-asan -j $(JOBS)
	cd $(BUILD)-asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:handle_sigill=1 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 FELT_SANITIZER=address \
	  ctest --output-on-failure -j $(JOBS)
	$(call PRUNE,$(BUILD)-asan)

test-tsan: deps
	@echo "== make test-tsan: start $$(date -u +%H:%M:%S)"
	cmake -S . -B $(BUILD)-tsan -G Ninja $(SAN_FLAGS) -DFELT_SANITIZE=thread \
	  "-DFELT_TEST_MODULES=rt;haptic_loop;server;transport;view" $(CMAKE_FLAGS)
	cmake --build $(BUILD)-tsan -j $(JOBS) --target felt_rt_tests felt_haptic_loop_tests felt_server_tests \
	  felt_transport_tests felt_view_tests
	cd $(BUILD)-tsan && TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$(CURDIR)/tests/transport/tsan.supp" \
	  FELT_SANITIZER=thread ctest --output-on-failure -j $(JOBS)
	$(call PRUNE,$(BUILD)-tsan)

clean:
	rm -rf $(BUILD) $(BUILD)-asan $(BUILD)-tsan
