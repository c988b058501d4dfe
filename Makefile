# The two README commands: `make demo` (the main job) and `make test` (the whole suite).
# Each creates a local .venv and installs the project (compiling the C core) on first use.
# `make check` is the quick tier for iterating on a change: no user-mode Linux, no multicast daemons,
# no firmware rebuilds (sanitizers, fuzzing, cross compiler, wheel), no scenario of several seconds.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SOURCES := $(shell find c_core firmware_sim dbc -type f \( -name '*.c' -o -name '*.h' -o -name '*.inc' -o -name '*.def' -o -name '*.dbc' -o -name '*.py' \)) pyproject.toml setup.py

.PHONY: demo test check bench install clean firmware-size firmware-image

demo: $(STAMP)
	$(BIN)/vehest-can demo $(ARGS)

test: $(STAMP)
	$(BIN)/python -m pytest $(ARGS)

check: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 -m "not slow and not multicast and not uml and not hostnet and not rebuild" $(ARGS)

bench: $(STAMP)
	$(BIN)/vehest-can bench $(ARGS)

install: $(STAMP)

# Each system's flash (text/data/bss) and worst-case stack for a Cortex-M4F (arm-none-eabi-gcc -Os).
firmware-size: $(STAMP)
	$(BIN)/python c_core/firmware_size.py $(ARGS)

# The ECU as an image for QEMU's mps2-an386 (Cortex-M4F; docs/firmware.md, "Processor in the loop"):
# built into build/firmware-image/<hash>/, its flash and RAM from the map file.
firmware-image: $(STAMP)
	$(BIN)/python c_core/firmware_image.py $(ARGS)

$(STAMP): $(SOURCES)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	# the runtime dependencies as wheels, for the test that installs the built wheel in a clean venv
	# offline (tests/test_wheel.py; CI runs the suite without network)
	mkdir -p build
	$(BIN)/python -c "import tomllib; print(*tomllib.load(open('pyproject.toml', 'rb'))['project']['dependencies'], sep='\n')" > build/runtime-requirements.txt
	$(BIN)/python -m pip download --quiet --dest build/wheelhouse -r build/runtime-requirements.txt
	touch $@

clean:
	rm -rf build $(VENV) vehest_can/_native*.so vehest_can/_native.c out
