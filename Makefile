# Two commands for a newcomer: `make demo` and `make test` (each installs what is missing first).
PY := .venv/bin/python
DEMO_DIR := out/demo

.PHONY: setup test test-slow demo bench lint clean

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
	@echo "demo pictures: $(DEMO_DIR)/house.png $(DEMO_DIR)/dataset-stats.png $(DEMO_DIR)/episode/*.png"

bench: setup
	$(PY) -m maniskill_tidy.bench

lint: setup
	$(PY) -m ruff check maniskill_tidy tests

clean:
	rm -rf out .pytest_cache
