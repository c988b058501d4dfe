# The two README commands: `make demo` (the main job) and `make test` (the whole suite).
# Each creates a local .venv and installs the project (compiling the C core) on first use.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SOURCES := $(shell find c_core firmware_sim dbc -type f \( -name '*.c' -o -name '*.h' -o -name '*.inc' -o -name '*.dbc' -o -name '*.py' \)) pyproject.toml setup.py

.PHONY: demo test bench install clean firmware-size

demo: $(STAMP)
	$(BIN)/vehest-can demo $(ARGS)

test: $(STAMP)
	$(BIN)/python -m pytest $(ARGS)

bench: $(STAMP)
	$(BIN)/vehest-can bench $(ARGS)

install: $(STAMP)

# Each system's flash (text/data/bss) and worst-case stack for a Cortex-M4F (arm-none-eabi-gcc -Os).
firmware-size: $(STAMP)
	$(BIN)/python c_core/firmware_size.py $(ARGS)

$(STAMP): $(SOURCES)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

clean:
	rm -rf build $(VENV) vehest_can/_native*.so vehest_can/_native.c out
