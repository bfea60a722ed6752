# The two set-up commands: `make demo` and `make test`. Everything else is a step of those.
JOBS ?= 2
BUILD ?= build
CMAKE_FLAGS ?= -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo
# The shared test meshes: beside the checkout, else where this workplace keeps them.
DATA_DIR ?= $(firstword $(wildcard $(abspath ../shared/data) /work/shared/data) $(abspath ../shared/data))
DEMO_SAMPLE ?= jittered:40
# make soak: clients and duration of the soak test (make test runs it for 60 s).
SOAK_SECONDS ?= 600
SOAK_CLIENTS ?= 16
# make fuzz: seconds per libFuzzer target (make test runs each for 40 s: a smoke run in CI;
# the seeds and what it finds are kept in build-fuzz/corpus for longer runs).
FUZZ_SECONDS ?= 600
FUZZERS = upload_fuzzer mesh_file_fuzzer partition_fuzzer request_fuzzer

.PHONY: all deps build test check lint-tests format check-format lint-python test-unit test-client-cpp test-thread-safety test-asan test-tsan test-asan-server test-soak soak test-fuzz fuzz lint-proto demo bench deploy-check clean

all: build

deps:
	bash scripts/install-deps.sh

$(BUILD)/build.ninja: | deps
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

build: deps $(BUILD)/build.ninja
	cmake --build $(BUILD) -j $(JOBS)

# API lint, C++ format, Python lint and types, clang's thread-safety analysis of the core, unit, service and
# fidelity tests; the core and algorithm
# tests again under ASan+UBSan, and with the service's logic under TSan; the server under
# ASan+UBSan for the service and client suites; the fuzzers.
test: lint-proto check-format lint-python lint-tests test-thread-safety check test-soak test-asan test-tsan \
  test-asan-server test-fuzz
	@echo "make test: all suites passed"

# The fast tier, for the edit-build-test loop: the build, then every ctest test (unit, fidelity,
# service), tests/, and both clients' suites against the real server; no lint, sanitizers, fuzzing
# or soak. CTEST_ARGS picks a subset by label: make check CTEST_ARGS="-L unit" (or -L fidelity,
# -L service, -LE slow).
check: test-unit test-client-cpp
	@echo "make check: the fast tier passed (make test runs everything CI runs)"

# The C++ client as a user gets it: built, installed, tested against the real server, and its
# examples built from a separate CMake project against the installed package.
test-client-cpp: build
	JOBS=$(JOBS) ACTOPO_DATA_DIR=$(DATA_DIR) bash client-cpp/check.sh $(abspath $(BUILD))

lint-proto: deps
	.tools/node_modules/.bin/buf lint proto

# The C++ house style (.clang-format): check-format fails on any file clang-format would change;
# format rewrites them.
CXX_SOURCES = $(shell git ls-files '*.cc' '*.h')
check-format: deps
	clang-format-14 --dry-run --Werror $(CXX_SOURCES)
	@echo "check-format: $(words $(CXX_SOURCES)) C++ files match .clang-format"

format:
	clang-format-14 -i $(CXX_SOURCES)

# The Python client: ruff (rules in client-py/pyproject.toml) and mypy --strict on the package;
# ruff with the same rules on tests/, bench/ and the ParaView plugin.
# Tests skip only through ACTOPO_SKIP (tests/testing/skip.h), which fails under $$ACTOPO_NO_SKIPS.
lint-tests:
	@if git grep -n 'GTEST_SKIP' -- '*.cc' '*.h' ':!tests/testing/skip.h'; then \
	  echo "lint-tests: use ACTOPO_SKIP (tests/testing/skip.h), not GTEST_SKIP"; exit 1; fi
	@echo "lint-tests: no GTEST_SKIP outside tests/testing/skip.h"

lint-python: deps
	cd client-py && ../.venv/bin/ruff check . ../tests ../bench ../paraview && ../.venv/bin/mypy actopo

# $(call ctest_run,DIR,ARGS): ctest on the tree DIR, then the reason of every skipped test. ctest
# shows a skipped test as "Skipped"; with $$ACTOPO_NO_SKIPS set (CI) it fails instead
# (tests/testing/gtest_main.cc).
ctest_run = ctest --test-dir $(1) --output-on-failure -j $(JOBS) $(2); status=$$?; \
  grep -h '^actopo-test-skip:' $(1)/Testing/Temporary/LastTest.log 2>/dev/null | sort -u; \
  exit $$status
CTEST_ARGS ?=
# The Python client's suite runs on JOBS processes (pytest-xdist), each starting its own server:
# 55 -> 32 s on 2 cores, 91 -> 56 s against the ASan server. tests/ stays on one: its time is
# a few long tests.
PYTEST_WORKERS ?= -n $(JOBS)
test-unit: build
	ACTOPO_DATA_DIR=$(DATA_DIR) $(call ctest_run,$(BUILD),$(CTEST_ARGS))
	ACTOPO_BUILD=$(abspath $(BUILD)) ACTOPO_DATA_DIR=$(DATA_DIR) .venv/bin/python -m pytest -q -rs tests
	ACTOPO_BUILD=$(abspath $(BUILD)) ACTOPO_DATA_DIR=$(DATA_DIR) .venv/bin/python -m pytest -q $(PYTEST_WORKERS) client-py/tests

# 16 clients doing everything at once against one server (scripts/soak.py), in two rounds: no
# unexpected status code; once idle after the second, no more heap in use, threads or
# descriptors than once idle after the first (the warm-up).
SOAK_HEAP_TOLERANCE ?= 0.05
soak: build
	ACTOPO_DATA_DIR=$(DATA_DIR) .venv/bin/python scripts/soak.py --build $(abspath $(BUILD)) \
	  --seconds $(SOAK_SECONDS) --clients $(SOAK_CLIENTS) --heap-tolerance $(SOAK_HEAP_TOLERANCE)

test-soak: build
	$(MAKE) soak SOAK_SECONDS=60

# libFuzzer targets (fuzz/), clang-14 with ASan+UBSan: upload decoding, mesh files, the
# partition, and every request message against an in-process server.
build-fuzz/build.ninja: | deps
	cmake -S . -B build-fuzz $(SANITIZE_CMAKE_FLAGS) -DCMAKE_CXX_COMPILER=clang++-14 \
	  -DACTOPO_SANITIZE=fuzz

fuzz: deps build-fuzz/build.ninja
	cmake --build build-fuzz -j $(JOBS) --target $(FUZZERS)
	bash fuzz/run.sh build-fuzz $(FUZZ_SECONDS)

test-fuzz:
	$(MAKE) fuzz FUZZ_SECONDS=40

# clang's thread-safety analysis (-Wthread-safety) of server/core and server/service, warnings
# as errors: every member annotated ABSL_GUARDED_BY is only touched with its mutex held
# (server/core/sync.h).
TSA_TARGETS = actopo_core actopo_service_logic actopo_service
# The analysis is clang's front end: no code generation worth optimizing, no debug information.
build-tsa/build.ninja: | deps
	cmake -S . -B build-tsa $(CMAKE_FLAGS) -DCMAKE_CXX_COMPILER=clang++-14 \
	  "-DCMAKE_CXX_FLAGS=-Wthread-safety -Werror" "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O0 -g0"

test-thread-safety: deps build-tsa/build.ninja
	cmake --build build-tsa -j $(JOBS) --target $(TSA_TARGETS)
	@echo "test-thread-safety: server/core and server/service pass clang -Wthread-safety -Werror"

# Sanitizer trees build less to stay fast. One ASan+UBSan tree serves two targets: test-asan
# builds the core and algorithm tests in it (no VTK, no gRPC) and runs them; test-asan-server
# then builds the server and the service's tests there, over the same instrumented core and
# algorithm libraries (a second tree compiled them again: 2 of CI's minutes). TSan builds those
# and the service's logic without gRPC (sessions, job leases, limits, background work). They
# compile at -O1 with line tables only (-g1), what the sanitizers' reports need: half the compile
# time of -O2 -g.
SANITIZE_CMAKE_FLAGS = $(CMAKE_FLAGS) "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG"
build-asan/build.ninja: | deps
	cmake -S . -B build-asan $(SANITIZE_CMAKE_FLAGS) -DACTOPO_SANITIZE=address -DACTOPO_CORE_ONLY=OFF
build-tsan/build.ninja: | deps
	cmake -S . -B build-tsan $(SANITIZE_CMAKE_FLAGS) -DACTOPO_SANITIZE=thread -DACTOPO_WITH_GRPC=OFF

# The tree lists every test binary of the project; those not built show up as "<target>_NOT_BUILT"
# and are left out. The core and algorithm tests are the unit tests built here.
ASAN_CORE_TESTS = actopo_core_test actopo_algorithms_test actopo_diagrams_test
test-asan: deps build-asan/build.ninja
	cmake --build build-asan -j $(JOBS) --target $(ASAN_CORE_TESTS)
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  $(call ctest_run,build-asan,-L unit -E '_NOT_BUILT$$')

# TSan needs a low-entropy address space on recent kernels; setarch -R runs without ASLR.
test-tsan: deps build-tsan/build.ninja
	cmake --build build-tsan -j $(JOBS)
	TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" \
	  setarch $$(uname -m) -R $(call ctest_run,build-tsan)

# The server under ASan+UBSan: its own service tests, then the Python and C++ client suites
# against it (gRPC and VTK themselves are not instrumented). The servers the client suites start
# write any report (a memory error, undefined behaviour, a leak at exit) into ASAN_REPORTS; the
# target fails if one is there, except the reader children's crashes on corrupt files.
ASAN_SERVER_TESTS = actopo-server actopo-read-mesh actopo_service_test actopo_session_manager_test
ASAN_REPORTS = $(abspath build-asan)/reports
ASAN_SERVER_ENV = ASAN_OPTIONS=detect_leaks=1:log_path=$(ASAN_REPORTS)/asan \
  UBSAN_OPTIONS=print_stacktrace=1:log_path=$(ASAN_REPORTS)/ubsan \
  ACTOPO_SERVER_BIN=$(abspath build-asan)/server/cmd/actopo-server \
  ACTOPO_BENCH_BIN=$(abspath $(BUILD))/server/cmd/actopo-bench ACTOPO_DATA_DIR=$(DATA_DIR)
test-asan-server: build build-asan/build.ninja
	cmake --build build-asan -j $(JOBS) --target $(ASAN_SERVER_TESTS)
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  ACTOPO_DATA_DIR=$(DATA_DIR) \
	  $(call ctest_run,build-asan/server/service,-E '_NOT_BUILT$$')
	rm -rf $(ASAN_REPORTS) && mkdir -p $(ASAN_REPORTS)
	$(ASAN_SERVER_ENV) ACTOPO_BUILD=$(abspath $(BUILD)) .venv/bin/python -m pytest -q $(PYTEST_WORKERS) client-py/tests
	test -d $(BUILD)/client || $(MAKE) test-client-cpp
	$(ASAN_SERVER_ENV) ctest --test-dir $(BUILD)/client --output-on-failure
	@reports=$$(grep -L actopo-read-mesh $(ASAN_REPORTS)/* 2>/dev/null); \
	  if [ -n "$$reports" ]; then cat $$reports; echo "test-asan-server: reports in $(ASAN_REPORTS)"; exit 1; fi
	@echo "test-asan-server: no ASan/UBSan report from the server"

# Starts the server on a built-in sample, runs jobs and relation queries through the Python
# CLI, prints results and statistics, stops the server.
demo: build
	BUILD=$(abspath $(BUILD)) DATA_DIR=$(DATA_DIR) bash scripts/demo.sh

# Lints and validates the deployment files, builds the server and client images with podman,
# runs the server and one job against it (scripts/deploy-check.sh; root or sudo; after make test).
deploy-check: deps
	DATA_DIR=$(DATA_DIR) bash scripts/deploy-check.sh

bench: build
	bash bench/compare_structures.sh

clean:
	rm -rf build build-asan build-tsan build-tsa build-fuzz
