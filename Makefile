# Two commands on a fresh machine: `make demo` and `make test`.
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
CARGO ?= cargo
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
BIN := target/release
OUT := out

.PHONY: all build venv test demo bench clean testdata

all: build

build:
	$(CARGO) build --release --workspace --bins

# numpy (and later onnxruntime) for the peer checks in the tests.
venv: $(VENV)/.stamp
$(VENV)/.stamp: scripts/requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r scripts/requirements.txt
	touch $@

test: venv
	DEM_PYTHON=$(abspath $(PY)) $(CARGO) test --workspace

clean:
	rm -rf $(OUT) .bench

# The committed test data set (see testdata/README.md).
testdata: build
	$(BIN)/dem-synth --out testdata --runs 60 --real-runs 20 --seed 1
