# The two commands of the README. Both install missing Debian packages first, then build Release in build/.
BUILD_DIR := build
PRESET := release
JOBS ?= $(shell nproc)

.PHONY: demo test build deps build-sanitize test-sanitize

deps:
	@bash scripts/deps.sh

build: deps
	@cmake --preset $(PRESET) >/dev/null
	@cmake --build --preset $(PRESET) -j $(JOBS)

demo: build
	@mkdir -p out
	$(BUILD_DIR)/apps/lancer/lancer render -o out/demo.png

test: build
	@ctest --preset $(PRESET) -j $(JOBS)

# The whole suite under AddressSanitizer + UBSan in build-sanitize/ (docs/robustness.md, "Sanitizers and
# limits"): any report fails the test that caused it.
build-sanitize: deps
	@cmake --preset sanitize >/dev/null
	@cmake --build --preset sanitize -j $(JOBS)

test-sanitize: build-sanitize
	@ctest --preset sanitize -j $(JOBS)
