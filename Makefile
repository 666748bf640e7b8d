# The README's two quick-start commands are `make smoke` (the runtime only: no test, lint or docs
# tools) and `make test` (adds them: the dev extra); CI calls `make setup` and `make test`.
VENV ?= .venv
BENCH := $(VENV)/bin/bench
PY := $(VENV)/bin/python

.PHONY: runtime setup smoke test lint docs anchors marl-eval clean-venv example-check docker-check cluster-check

# The runtime (what `bench` needs to run and report), then the dev extra on top of it.
$(VENV)/.installed: pyproject.toml constraints.txt scripts/setup.sh
	VENV=$(VENV) bash scripts/setup.sh
	touch $@

$(VENV)/.installed-dev: $(VENV)/.installed
	VENV=$(VENV) EXTRAS=dev bash scripts/setup.sh
	touch $@

## The runtime only (what `make smoke` installs).
runtime: $(VENV)/.installed

## The runtime and the test, lint and docs tools (the dev extra).
setup: $(VENV)/.installed-dev

## Set up the runtime, run the smoke grid on this machine and build its report.
smoke: runtime
	$(BENCH) run --grid smoke --out results/smoke
	$(BENCH) report --run results/smoke

## Set up and run the whole test suite (2 workers).
test: setup
	$(PY) -m pytest -q -n 2 --dist loadfile -m "not netns"

## Build the Docker image with a private dockerd and check smoke + report in it against the host
## (docs/deployment.md). HOST_RUN=DIR reuses a host smoke run.
docker-check: setup
	bash scripts/docker_check.sh

## The cluster recipe on three network-namespace hosts, one killed mid-run (root; docs/deployment.md).
## CLUSTER_REFERENCE=DIR reuses a single-machine smoke run.
cluster-check: setup
	$(PY) -m pytest -q -s -p no:cacheprovider -m netns tests/scripts/test_cluster_check.py

## The worked outside method packages end to end, with no edit to this package.
example-check: setup
	VENV=$(VENV) bash scripts/example_check.sh

lint: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy
	$(VENV)/bin/lint-imports
	$(VENV)/bin/hadolint Dockerfile

## Build the documentation site (mkdocs.yml) into site/; --strict fails on a broken link or reference.
docs: setup
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict

## POGEMA and RWARE speed anchors live in their own venv (POGEMA needs pydantic 1);
## bench/perf/env.py drives them through bench/perf/anchors_script.py.
anchors: .anchors-venv/.installed

.anchors-venv/.installed: bench/perf/anchors-requirements.txt
	python3 -m venv .anchors-venv
	.anchors-venv/bin/pip install --quiet --upgrade pip
	.anchors-venv/bin/pip install --quiet -r bench/perf/anchors-requirements.txt
	.anchors-venv/bin/python -c "import pogema, rware; print('anchors ready: pogema', pogema.__version__)"
	touch $@

## marl-eval (PyPI id-marl-eval) pins pandas==1.4.4, which has no build for Python 3.11, so it
## lives in its own venv, installed without its declared pins; tests/bench/export/test_export.py loads
## `bench export --format marl-eval` with its data-processing functions there.
marl-eval: .marl-eval-venv/.installed

.marl-eval-venv/.installed: bench/export/marl-eval-requirements.txt
	python3 -m venv .marl-eval-venv
	.marl-eval-venv/bin/pip install --quiet --upgrade pip
	.marl-eval-venv/bin/pip install --quiet -r bench/export/marl-eval-requirements.txt
	.marl-eval-venv/bin/pip install --quiet --no-deps "id-marl-eval==0.0.4"
	.marl-eval-venv/bin/python -c "import marl_eval.utils.data_processing_utils, marl_eval.utils.diagnose_data_errors; print('marl-eval ready')"
	touch $@

clean-venv:
	rm -rf $(VENV) .anchors-venv .marl-eval-venv
