# The two commands of the README. Both install missing Debian packages first, then build Release in build/.
BUILD_DIR := build
PRESET := release
JOBS ?= $(shell nproc)

.PHONY: demo test build deps

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
