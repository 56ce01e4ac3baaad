# The two commands of the README. Both install missing Debian packages first, then build Release in build/:
# `make demo` only the command-line tool it runs, `make test` everything the suite tests.
PRESET := release
# The preset's binaryDir (CMakePresets.json): build/ for release, build-PRESET/ for the others.
BUILD_DIR := $(if $(filter release,$(PRESET)),build,build-$(PRESET))
JOBS ?= $(shell nproc)
# The interpreter the Python module is built for: the first python3 on PATH that imports NumPy (a pyenv or
# other python3 may come before Debian's, which scripts/deps.sh gives NumPy). Override with PYTHON=...
PYTHON ?= $(shell for p in $$(which -a python3 2>/dev/null); do $$p -c 'import numpy' 2>/dev/null && { echo $$p; break; }; done)
CONFIGURE_FLAGS := $(if $(PYTHON),-DPython3_EXECUTABLE=$(PYTHON))

.PHONY: demo test build configure deps build-sanitize test-sanitize

deps:
	@bash scripts/deps.sh

# The presets use Ninja. A build folder that the Unix Makefiles generator configured (before them) loses its
# cache first, since CMake refuses to change a folder's generator.
forget_makefiles = @if grep -qs '^CMAKE_GENERATOR:INTERNAL=Unix Makefiles' $(1)/CMakeCache.txt; then \
	rm -rf $(1)/CMakeCache.txt $(1)/CMakeFiles; fi

configure: deps
	$(call forget_makefiles,$(BUILD_DIR))
	@cmake --preset $(PRESET) $(CONFIGURE_FLAGS) >/dev/null

build: configure
	@cmake --build --preset $(PRESET) -j $(JOBS)

demo: configure
	@cmake --build --preset $(PRESET) -j $(JOBS) --target lancer_cli
	@mkdir -p out
	$(BUILD_DIR)/apps/lancer/lancer render -o out/demo.png

test: build
	@ctest --preset $(PRESET) -j $(JOBS)

# The whole suite under AddressSanitizer + UBSan in build-sanitize/ (docs/robustness.md, "Sanitizers and
# limits"): any report fails the test that caused it.
build-sanitize: deps
	$(call forget_makefiles,build-sanitize)
	@cmake --preset sanitize >/dev/null
	@cmake --build --preset sanitize -j $(JOBS)

test-sanitize: build-sanitize
	@ctest --preset sanitize -j $(JOBS)
