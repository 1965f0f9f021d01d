# The README's commands. Each target installs missing Debian packages, configures and builds
# (Release, Ninja, ccache when present) before doing its job.
BUILD_DIR ?= build
OUT_DIR   ?= out
JOBS      ?= $(shell nproc)
VISCERA   := $(BUILD_DIR)/apps/viscera/viscera
CCACHE    := $(shell command -v ccache 2>/dev/null)
CMAKE_FLAGS := -G Ninja -DCMAKE_BUILD_TYPE=Release $(if $(CCACHE),-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)

.PHONY: all deps configure build demo test bench clean

all: build

deps:
	@bash scripts/install-deps.sh

$(BUILD_DIR)/build.ninja: | deps
	cmake -S . -B $(BUILD_DIR) $(CMAKE_FLAGS)

configure: deps
	cmake -S . -B $(BUILD_DIR) $(CMAKE_FLAGS)

build: deps $(BUILD_DIR)/build.ninja
	cmake --build $(BUILD_DIR) -j $(JOBS)

demo: build
	@rm -rf $(OUT_DIR)/demo.tmp
	$(VISCERA) run scenes/gel_phantom.xml --time 0.5 --out $(OUT_DIR)/demo --summary $(OUT_DIR)/demo/summary.json
	@echo
	@echo "Demo outputs: $(OUT_DIR)/demo/ (open $(OUT_DIR)/demo/gel_phantom.pvd in ParaView; summary in $(OUT_DIR)/demo/summary.json)"

test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS)

bench: build
	$(BUILD_DIR)/tests/bench/viscera_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

clean:
	rm -rf $(BUILD_DIR)
