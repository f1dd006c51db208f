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

.PHONY: all build venv venv-torch test demo bench clean testdata eval-ci eval-baseline thesis-table fuzz

all: build

build:
	$(CARGO) build --release --workspace --bins

# numpy (and later onnxruntime) for the peer checks in the tests.
venv: $(VENV)/.stamp
$(VENV)/.stamp: scripts/requirements.txt python/pyproject.toml python/demstream/__init__.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r scripts/requirements.txt
	$(PY) -m pip install -q ./python
	touch $@

test: venv
	DEM_PYTHON=$(abspath $(PY)) $(CARGO) test --workspace

# Longer runs of the readers' property tests, then the cargo-fuzz targets in
# fuzz/ (nightly toolchain; cargo-fuzz is installed if missing).
FUZZ_SECONDS ?= 60
FUZZ_TARGETS := npy_reader csv_tables sensor_json
fuzz:
	PROPTEST_CASES=20000 $(CARGO) test --release -p dem-core --test properties
	command -v cargo-fuzz >/dev/null || $(CARGO) install cargo-fuzz --locked
	for t in $(FUZZ_TARGETS); do $(CARGO) +nightly fuzz run $$t -- -max_total_time=$(FUZZ_SECONDS) || exit 1; done

# PyTorch (CPU) for the training benchmark only: large, kept out of the tests.
TORCH_VENV := .venv-torch
venv-torch: $(TORCH_VENV)/.stamp
$(TORCH_VENV)/.stamp:
	$(PYTHON) -m venv $(TORCH_VENV)
	$(TORCH_VENV)/bin/pip install -q --upgrade pip
	$(TORCH_VENV)/bin/pip install -q torch onnx numpy
	touch $@

# The validation error table against testdata/eval_baseline.csv (exit 1 when worse).
eval-ci: build
	BIN=$(BIN) OUT=$(OUT)/eval_ci bash scripts/eval_ci.sh
eval-baseline: build
	BIN=$(BIN) OUT=$(OUT)/eval_ci UPDATE_BASELINE=1 bash scripts/eval_ci.sh
# The thesis's table 7.x on testdata: 6 rows and pictures (three trainings, ~10 min).
thesis-table: build
	BIN=$(BIN) OUT=$(OUT)/thesis bash scripts/thesis_table.sh

clean:
	rm -rf $(OUT) .bench

# Speed against the peers, measured in one run (not part of the tests).
bench: build venv
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_npy.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_synth.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_prep.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_gap.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_apply.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_memory.sh
	PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_import.sh
	$(MAKE) venv-torch
	$(TORCH_VENV)/bin/python scripts/torch_export.py .bench/apply_torch_w32.onnx --width 32 --seed 1
	MODEL=.bench/apply_torch_w32.onnx REPORT=apply_torch.txt PY=$(PY) BIN=$(BIN) OUT=.bench bash scripts/bench_apply.sh
	$(CARGO) build --release -p dem-nn --example step_speed
	TORCH_PY=$(TORCH_VENV)/bin/python BIN=$(BIN) OUT=.bench bash scripts/bench_train.sh
	@echo "Reports: .bench/npy.txt .bench/synth.txt .bench/prep.txt .bench/gap.txt .bench/apply.txt .bench/apply_torch.txt .bench/import.txt .bench/train.txt"

# Records of testdata/real.npy (and the same poses in testdata/sim.npy) that
# show the effects: a startup frame, flat ground, stairs up (approach, on
# them), stairs down (at the edge, on them), a pallet (approach, on it,
# leaving it, twice), stairs down again.
DEMO_RECORDS := 0,230,48,68,103,110,137,148,155,398,413,344
STAGES := occlusion smoothing noise dropout fov
TD := testdata
# Epochs of the demo's G_Y (dem-train's default, 30: ~3 s an epoch on 2 cores).
DEMO_EPOCHS ?= 30

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
	BIN=$(BIN) $(PY) scripts/effect_table.py $(TD)/sim.npy measured=$(TD)/real.npy $(foreach s,$(STAGES),no-$(s)=$(OUT)/no-$(s)/real.npy) \
	    | tee $(OUT)/effects.md
	@echo "== 3. data preparation: filter -> pair -> clean pallets -> fill startup frames"
	$(BIN)/dem-filter --labels $(TD)/sim_labels.csv --drop-other --unique $(TD)/sim.npy -o $(OUT)/prep/sim.npy \
	    --emit-index $(OUT)/prep/sim_index.csv --emit-labels $(OUT)/prep/sim_labels.csv
	$(BIN)/dem-filter --labels $(TD)/real_labels.csv --drop-other $(TD)/real.npy -o $(OUT)/prep/real.npy \
	    --emit-labels $(OUT)/prep/real_labels.csv
	$(BIN)/dem-pair --by content --sim $(OUT)/prep/sim.npy --real $(OUT)/prep/real.npy \
	    --sim-labels $(OUT)/prep/sim_labels.csv --k 3 --val-fraction 0.5 --seed 1 -o $(OUT)/prep/pairs.csv
	$(BIN)/dem-clean-pallet --labels $(OUT)/prep/sim_labels.csv $(OUT)/prep/sim.npy -o $(OUT)/prep/sim_clean.npy
	$(BIN)/dem-fill-nans --min-missing 0.3 --keep-fraction 0.2 --seed 1 $(OUT)/prep/real.npy -o $(OUT)/prep/real_filled.npy
	$(BIN)/dem-filter --labels $(OUT)/prep/sim_labels.csv --terrain pallet $(OUT)/prep/sim.npy -o $(OUT)/prep/pallets.npy
	$(BIN)/dem-filter --labels $(OUT)/prep/sim_labels.csv --terrain pallet $(OUT)/prep/sim_clean.npy -o $(OUT)/prep/pallets_clean.npy
	$(BIN)/dem-render --compare $(OUT)/prep/pallets.npy $(OUT)/prep/pallets_clean.npy --row-labels sim,cleaned \
	    --start 6 --count 12 --title "dem-clean-pallet: sim pallets before and after" -o $(OUT)/pallets_cleaned.png
	$(BIN)/dem-filter --labels $(OUT)/prep/real_labels.csv --max-time 0 $(OUT)/prep/real.npy -o $(OUT)/prep/startup.npy
	$(BIN)/dem-filter --labels $(OUT)/prep/real_labels.csv --max-time 0 $(OUT)/prep/real_filled.npy \
	    -o $(OUT)/prep/startup_filled.npy
	$(BIN)/dem-render --compare $(OUT)/prep/startup.npy $(OUT)/prep/startup_filled.npy --row-labels measured,filled \
	    --title "dem-fill-nans: the first frame of each run before and after" -o $(OUT)/startup_filled.png
	@echo "== 4. train G_Y on the prepared data (Cycle GAN + pairs), export to ONNX, evaluate on the val split"
	rm -rf $(OUT)/train
	$(BIN)/dem-train --sim $(OUT)/prep/sim.npy --real $(OUT)/prep/real.npy --pairs $(OUT)/prep/pairs.csv \
	    --out $(OUT)/train --epochs $(DEMO_EPOCHS) --seed 1
	$(BIN)/dem-train export $(OUT)/train -o $(OUT)/gy.onnx
	$(BIN)/dem-train curves $(OUT)/train -o $(OUT)/curves.png
	$(BIN)/dem-eval --sim $(OUT)/prep/sim.npy --real $(OUT)/prep/real.npy --pairs $(OUT)/prep/pairs.csv \
	    --split val --identity --format csv -o $(OUT)/train/identity.csv
	$(BIN)/dem-eval --sim $(OUT)/prep/sim.npy --real $(OUT)/prep/real.npy --pairs $(OUT)/prep/pairs.csv \
	    --split val --model $(OUT)/gy.onnx --name paired-data --format csv -o $(OUT)/train/model.csv \
	    --emit-input $(OUT)/train/input.npy --emit-pred $(OUT)/train/pred.npy --emit-closest $(OUT)/train/closest.npy
	awk 'NR == 1 || FNR > 1' $(OUT)/train/identity.csv $(OUT)/train/model.csv > $(OUT)/train/table.csv
	$(BIN)/dem-apply --model $(OUT)/gy.onnx $(OUT)/train/input.npy -o $(OUT)/train/apply.npy
	$(BIN)/dem-render --compare $(OUT)/train/input.npy $(OUT)/train/closest.npy $(OUT)/train/pred.npy \
	    --row-labels input,closest-real,generated --error-rows 2,1 --start 0 --count 12 \
	    --title "G_Y on val keys: sim input, closest real, generated (eq. 7.1 pair error under each)" -o $(OUT)/generated.png
	$(BIN)/dem-eval --sim $(OUT)/prep/sim.npy --real $(OUT)/prep/real.npy --pairs $(OUT)/prep/pairs.csv \
	    --split val --identity --name identity --format md -o $(OUT)/train/identity.md
	$(BIN)/dem-eval --sim $(OUT)/prep/sim.npy --real $(OUT)/prep/real.npy --pairs $(OUT)/prep/pairs.csv \
	    --split val --model $(OUT)/gy.onnx --name paired-data --format md -o $(OUT)/train/model.md
	cat $(OUT)/train/identity.md <(tail -n +3 $(OUT)/train/model.md) | tee $(OUT)/train/table.md
	@echo "== 4b. downstream: flipper regressor and terrain classifier trained on sim, G_Y(sim) (holes thresholded and drawn, then startup by time), sensor(sim), measured"
	BIN=$(BIN) TD=$(TD) OUT=$(OUT)/transfer bash scripts/transfer.sh
	@echo "== 5. CI guard: the validation table of a tiny model against testdata/eval_baseline.csv"
	BIN=$(BIN) OUT=$(OUT)/eval_ci bash scripts/eval_ci.sh
	@echo "== 6. dem-gap: name the sim-to-real gap, leaving one emulator stage out at a time"
	BIN=$(BIN) OUT=$(OUT) PY=$(PY) TD=$(TD) bash scripts/gap_demo.sh
	@echo "== 7. dem-import: robot recordings (a ROS 1 bag, a ROS 2 MCAP bag) back into DEMs"
	BIN=$(BIN) OUT=$(OUT) PY=$(PY) bash scripts/import_demo.sh
	@echo
	@echo "Pictures:"
	@echo "  $(OUT)/generated.png         G_Y: sim input, closest real, generated, pair error under each"
	@echo "  $(OUT)/curves.png            G_Y's training curves: losses per epoch, val pair error"
	@echo "  $(OUT)/sim_vs_measured.png   sim and measured DEMs side by side (holes, shadows, smoothing, startup rows)"
	@echo "  $(OUT)/effects.png           the same poses with each emulator stage switched off"
	@echo "  $(OUT)/pallets_cleaned.png   sim pallets before and after dem-clean-pallet"
	@echo "  $(OUT)/startup_filled.png    startup frames before and after dem-fill-nans"
	@echo "  $(OUT)/import/import.png     dem-import of a ROS 1 bag and a ROS 2 MCAP bag vs the emulator's DEMs of the same poses"
	@echo "Table: $(OUT)/effects.md (missing cells, residuals and Identity error per emulator stage)"
	@echo "Data: $(OUT)/prep/ (sim keys, real, pairs.csv, cleaned and filled streams)"
	@echo "Model: $(OUT)/gy.onnx (dem-apply --model $(OUT)/gy.onnx < sim.npy > realistic.npy); run: $(OUT)/train/"
	@echo "Tables: $(OUT)/train/table.md (Identity vs G_Y: pair error, height error, roughness, gap), $(OUT)/eval_ci/compare.txt (CI guard)"
	@echo "Transfer: $(OUT)/transfer/transfer.txt (flipper and terrain models trained on sim, G_Y(sim) (holes thresholded and drawn, then startup by time), sensor(sim), measured)"
	@echo "Gap: $(OUT)/gap/summary.md (effects named per emulator stage left out), $(OUT)/gap/exact-paired/report.md (report with pictures)"

# The committed test data set (see testdata/README.md).
testdata: build
	$(BIN)/dem-synth --out testdata --runs 60 --real-runs 20 --seed 1
