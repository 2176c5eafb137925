# The two commands of the README, and a few conveniences.
#   make demo   install what the program needs, build only it, run the main job
#   make test   install what is missing, build, run the whole test suite
#               (ctest while the fuzzers build, then every decoder's
#               libFuzzer target for 10 s)

BUILD_DIR ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?=

.PHONY: demo test setup build bench format clean

setup:
	@scripts/setup

# Configured with the tests every time: a build first configured by `make
# demo` (tests off, and without the optional ROS 1 side, whose packages the
# demo does not install) gets them now.
build: setup
	cmake -S . -B $(BUILD_DIR) -G Ninja -DCMAKE_BUILD_TYPE=Release -DDCL_BUILD_TESTS=ON $(CMAKE_FLAGS)
	cmake --build $(BUILD_DIR) -j $(JOBS)

# Only the program: the packages to build it, and its own targets. A build
# folder configured before (by `make test`) keeps its configuration.
demo:
	@scripts/setup --demo
	@test -f $(BUILD_DIR)/build.ninja || cmake -S . -B $(BUILD_DIR) -G Ninja \
	  -DCMAKE_BUILD_TYPE=Release -DDCL_BUILD_TESTS=OFF $(CMAKE_FLAGS)
	cmake --build $(BUILD_DIR) -j $(JOBS) --target dcl-slam
	$(BUILD_DIR)/apps/dcl-slam demo

# The fuzzers' clang build runs beside ctest at the lowest priority: it takes
# the cycles the tests leave (the live robots' tests wait on real time), and
# the tests keep their cores whenever they want them. It has a session of its
# own, whose process group a failing ctest stops; where the kernel groups the
# scheduling by session (autogroup), that group gets the lowest priority too,
# or it would share the cores half and half with ctest's.
FUZZ_BUILD_LOG = $(BUILD_DIR)/fuzz-build.log
FUZZ_BUILD = { echo 19 >/proc/self/autogroup; } 2>/dev/null; exec nice -n 19 scripts/fuzz --build-only
test: build
	@scripts/setup --npm-prefix $(BUILD_DIR)/npm
	@setsid -w sh -c '$(FUZZ_BUILD)' >$(FUZZ_BUILD_LOG) 2>&1 & fuzz=$$!; \
	  ctest --test-dir $(BUILD_DIR) --output-on-failure -j $(JOBS) || \
	    { kill -- -$$fuzz 2>/dev/null; exit 1; }; \
	  wait $$fuzz || { tail -n 40 $(FUZZ_BUILD_LOG); echo "fuzzers' build failed" >&2; exit 1; }
	scripts/fuzz --seconds 10

bench: setup
	cmake -S . -B $(BUILD_DIR)-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DDCL_BUILD_TESTS=OFF -DDCL_BUILD_BENCHMARKS=ON
	cmake --build $(BUILD_DIR)-bench -j $(JOBS)
	$(BUILD_DIR)-bench/bench/dcl_bench

format:
	git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

clean:
	rm -rf $(BUILD_DIR) $(BUILD_DIR)-bench build-fuzz
