# laminid — two commands for a newcomer: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup bytecode demo example-frf test test-all bench clean

# uv (from PyPI, into the venv) installs the packages in ~4 s where pip takes ~26 s (fresh
# machine, empty caches); pip where uv cannot be had. With CHOLMOD (cvxopt, the 'fast' extra)
# where it installs; else the banded Cholesky.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	if $(BIN)/python -m pip install --quiet uv; then \
	  install="$(BIN)/uv pip install --quiet --python $(BIN)/python"; \
	else \
	  $(BIN)/python -m pip install --quiet --upgrade pip; \
	  install="$(BIN)/python -m pip install --quiet"; \
	fi; \
	$$install -e '.[fast,test]' || \
	  { echo "cvxopt (CHOLMOD) did not install: laminid uses its banded Cholesky"; \
	    $$install -e '.[test]'; }
	touch $(STAMP)

setup: $(STAMP)

# bytecode of the package (editable install), tests and scripts, written once: every CLI child
# process and test worker otherwise compiles ~25 000 lines again where PYTHONDONTWRITEBYTECODE
# is set, as on CI (~0.2 s a process; the subprocess-heavy test files ran 56 s instead of 65 s).
# And of the venv's packages, which uv installs without it: dask, distributed, tornado,
# fontTools (matplotlib's PDF fonts), pyvisa, pyuff were compiled again by every test worker
# and CLI child process that imported them (a Dask batch's workers too); make test's
# subprocess-heavy files 83 s instead of 89 s, 128 s CPU instead of 139 s. Once ~10 s; then
# ~0.2 s (only the files that changed); a file that does not compile is left to the import.
bytecode: setup
	$(BIN)/python -m compileall -q laminid_cli tests scripts benchmarks
	$(BIN)/python -m compileall -q -j 0 \
	  "$$($(BIN)/python -c 'import sysconfig; print(sysconfig.get_path("purelib"))')" \
	  > /dev/null || echo "some of the venv's packages were not compiled (make test runs the same)"

demo: bytecode
	$(BIN)/laminid modes specimens/example1/S1.1.yaml
	@mkdir -p out
	$(BIN)/laminid identify specimens/example1/S1.1.yaml -o out/S1.1.result.h5 --force

# a synthetic impact test of S1.1 (FRFs + specimen without frequencies), for fit-frf and damping
example-frf: setup
	$(BIN)/python scripts/example_frf.py --out out/example-frf

test: bytecode
	$(BIN)/python -m pytest -q -n 2

# LAMINID_FUZZ_SCALE: the fuzz tests (tests/test_fuzz.py) run 10 times their default cases
test-all: bytecode
	LAMINID_FUZZ_SCALE=10 $(BIN)/python -m pytest -q -n 2 -m 'not hardware'

bench: setup
	for f in benchmarks/bench_*.py; do $(BIN)/python $$f || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info
