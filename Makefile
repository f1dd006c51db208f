# Two commands on a fresh machine: `make demo` and `make test`.
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
CARGO ?= cargo
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
BIN := target/release
OUT := out
comma := ,

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

# Speed against the peers, measured in one run (not part of the tests).
bench: build venv
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_npy.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_synth.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_prep.sh
	@echo "Reports: .bench/npy.txt .bench/synth.txt .bench/prep.txt"

# Records of testdata/real.npy (and the same poses in testdata/sim.npy) that
# show the effects: a startup frame, flat ground, stairs up (approach, on
# them), stairs down (at the edge, on them), a pallet (approach, on it,
# leaving it, twice), stairs down again.
DEMO_RECORDS := 0,230,48,68,103,110,137,148,155,398,413,344
STAGES := occlusion smoothing noise dropout fov
TD := testdata

demo: build venv
	@mkdir -p $(OUT)/prep
	@echo "== 1. sim and measured DEMs of the same poses (testdata/, made by dem-synth)"
	$(BIN)/dem-render --compare $(TD)/sim.npy $(TD)/real.npy --row-labels sim,measured \
	    --error-rows 2,1 --indices $(DEMO_RECORDS) \
	    --title "sim and measured DEMs of the same poses, eq. 7.1 error under each" -o $(OUT)/sim_vs_measured.png
	@echo "== 2. the same runs measured with one physical effect hidden at a time"
	for s in $(STAGES); do \
	  $(BIN)/dem-synth --out $(OUT)/no-$$s --runs 20 --real-runs 20 --seed 1 --no-$$s 2>/dev/null; done
	$(BIN)/dem-render --compare $(TD)/sim.npy $(TD)/real.npy $(foreach s,$(STAGES),$(OUT)/no-$(s)/real.npy) \
	    --row-labels sim,measured,$(subst $(eval) ,$(comma),$(foreach s,$(STAGES),no-$(s))) \
	    --indices $(DEMO_RECORDS) --title "measured with each emulator stage switched off" -o $(OUT)/effects.png
	$(PY) scripts/effect_table.py $(TD)/sim.npy measured=$(TD)/real.npy $(foreach s,$(STAGES),no-$(s)=$(OUT)/no-$(s)/real.npy) \
	    | tee $(OUT)/effects.md
	@echo "== 3. data preparation: filter -> pair -> clean pallets -> fill startup frames"
	$(BIN)/dem-filter --labels $(TD)/sim_labels.csv --drop-other --unique $(TD)/sim.npy -o $(OUT)/prep/sim.npy \
	    --emit-index $(OUT)/prep/sim_index.csv --emit-labels $(OUT)/prep/sim_labels.csv
	$(BIN)/dem-filter --labels $(TD)/real_labels.csv --drop-other $(TD)/real.npy -o $(OUT)/prep/real.npy \
	    --emit-labels $(OUT)/prep/real_labels.csv
	$(BIN)/dem-pair --by content --sim $(OUT)/prep/sim.npy --real $(OUT)/prep/real.npy \
	    --sim-labels $(OUT)/prep/sim_labels.csv --k 3 --seed 1 -o $(OUT)/prep/pairs.csv
	$(BIN)/dem-clean-pallet --labels $(OUT)/prep/sim_labels.csv $(OUT)/prep/sim.npy -o $(OUT)/prep/sim_clean.npy
	$(BIN)/dem-fill-nans --min-missing 0.3 --keep-fraction 0.2 --seed 1 $(OUT)/prep/real.npy -o $(OUT)/prep/real_filled.npy
	$(BIN)/dem-filter --labels $(OUT)/prep/sim_labels.csv --terrain pallet $(OUT)/prep/sim.npy -o $(OUT)/prep/pallets.npy
	$(BIN)/dem-filter --labels $(OUT)/prep/sim_labels.csv --terrain pallet $(OUT)/prep/sim_clean.npy -o $(OUT)/prep/pallets_clean.npy
	$(BIN)/dem-render --compare $(OUT)/prep/pallets.npy $(OUT)/prep/pallets_clean.npy --row-labels sim,cleaned \
	    --start 6 --count 12 --title "dem-clean-pallet: sim pallets before and after" -o $(OUT)/pallets_cleaned.png
	$(BIN)/dem-filter --index <(awk -F, 'NR>1 && $$7==0 {print $$1}' $(OUT)/prep/real_labels.csv | sed '1i index') \
	    $(OUT)/prep/real.npy -o $(OUT)/prep/startup.npy
	$(BIN)/dem-filter --index <(awk -F, 'NR>1 && $$7==0 {print $$1}' $(OUT)/prep/real_labels.csv | sed '1i index') \
	    $(OUT)/prep/real_filled.npy -o $(OUT)/prep/startup_filled.npy
	$(BIN)/dem-render --compare $(OUT)/prep/startup.npy $(OUT)/prep/startup_filled.npy --row-labels measured,filled \
	    --title "dem-fill-nans: the first frame of each run before and after" -o $(OUT)/startup_filled.png
	@echo
	@echo "Pictures:"
	@echo "  $(OUT)/sim_vs_measured.png   sim and measured DEMs side by side (holes, shadows, smoothing, startup rows)"
	@echo "  $(OUT)/effects.png           the same poses with each emulator stage switched off"
	@echo "  $(OUT)/pallets_cleaned.png   sim pallets before and after dem-clean-pallet"
	@echo "  $(OUT)/startup_filled.png    startup frames before and after dem-fill-nans"
	@echo "Table: $(OUT)/effects.md (missing cells, residuals and Identity error per emulator stage)"
	@echo "Data: $(OUT)/prep/ (sim keys, real, pairs.csv, cleaned and filled streams)"

# The committed test data set (see testdata/README.md).
testdata: build
	$(BIN)/dem-synth --out testdata --runs 60 --real-runs 20 --seed 1
