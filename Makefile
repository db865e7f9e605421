# Two commands for a newcomer: `make demo` and `make test` (each installs what is missing first).
PY := .venv/bin/python
DEMO_DIR := out/demo

.PHONY: setup test test-slow demo bench leaderboard lint clean

setup:
	@bash scripts/setup.sh

test: setup
	$(PY) -m pytest -q

test-slow: setup
	$(PY) -m pytest -q -m slow

demo: setup
	$(PY) -m maniskill_tidy.cli generate --houses 12 --seed 0 --out $(DEMO_DIR)/dataset --workers 2
	$(PY) -m maniskill_tidy.cli validate $(DEMO_DIR)/dataset
	$(PY) -m maniskill_tidy.cli dataset-stats $(DEMO_DIR)/dataset --png $(DEMO_DIR)/dataset-stats.png
	$(PY) -m maniskill_tidy.cli show-house --dataset $(DEMO_DIR)/dataset --split train --index 0 --task 0 --out $(DEMO_DIR)/house.png
	$(PY) -m maniskill_tidy.cli run-episode --dataset $(DEMO_DIR)/dataset --split test --setting I --episode 0 --steps 30 --out $(DEMO_DIR)/episode
	$(PY) -m maniskill_tidy.cli show-map --dataset $(DEMO_DIR)/dataset --split test --episode 0 --agent agent_2 --out $(DEMO_DIR)/map.png
	$(PY) -m maniskill_tidy.cli eval --policy expert --setting I --split test --episodes 5 --dataset $(DEMO_DIR)/dataset --record all --out $(DEMO_DIR)
	$(PY) -m maniskill_tidy.cli eval --policy heuristic-broadcast --setting I --split test --episodes 2 --dataset $(DEMO_DIR)/dataset --record all --out $(DEMO_DIR)
	$(PY) -m maniskill_tidy.cli leaderboard --root $(DEMO_DIR)/eval
	@echo "demo pictures: $(DEMO_DIR)/house.png $(DEMO_DIR)/dataset-stats.png $(DEMO_DIR)/episode/*.png $(DEMO_DIR)/map.png"
	@echo "demo evaluation: $(DEMO_DIR)/eval/LEADERBOARD.md; recordings: $(DEMO_DIR)/recordings (maniskill-tidy replay FILE)"

bench: setup
	$(PY) -m maniskill_tidy.bench

# The leaderboard's runs: the 120-house dataset, then every policy on its test split (each
# `eval` resumes if interrupted; rerunning skips finished episodes).
DATA120 ?= data/tidy120
EVAL = $(PY) -m maniskill_tidy.cli eval --split test --dataset $(DATA120) --workers 2
leaderboard: setup
	test -f $(DATA120)/manifest.json || $(PY) -m maniskill_tidy.cli generate --houses 120 --seed 0 --workers 2 --out $(DATA120)
	$(EVAL) --policy expert --setting I
	$(EVAL) --policy expert --setting II
	$(EVAL) --policy random --setting I --episodes 200
	$(EVAL) --policy random --setting II --episodes 200
	for p in sa heuristic-none heuristic-detection heuristic-broadcast heuristic-central; do \
	  $(EVAL) --policy $$p --setting I --episodes 100 || exit 1; done
	for p in sa heuristic-none heuristic-detection heuristic-broadcast heuristic-central; do \
	  $(EVAL) --policy $$p --setting II --episodes 100 || exit 1; done
	$(PY) -m maniskill_tidy.cli leaderboard

lint: setup
	$(PY) -m ruff check maniskill_tidy tests

clean:
	rm -rf out .pytest_cache
