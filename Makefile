# facadeforge — `make demo` and `make test` each build the environment from nothing, then run.
PYTHON ?= python3
UV_VERSION := 0.13.8
TOOLS := .tools
UV := $(TOOLS)/bin/uv
VENV := .venv
export UV_PROJECT_ENVIRONMENT := $(VENV)
export UV_PYTHON_DOWNLOADS := never

.PHONY: env train-env bench-env prt-env demo test lint docs bench fuzz cjval gltf-validator clean web screenshots

$(UV):
	$(PYTHON) -m venv $(TOOLS)
	$(TOOLS)/bin/pip install --quiet --disable-pip-version-check uv==$(UV_VERSION)

# Bytecode compiled at install (uv's --compile-bytecode for the dependencies, compileall for
# our sources): with PYTHONDONTWRITEBYTECODE set, as on CI machines, every command otherwise
# recompiles some 600 modules (1.3 s of a 6 s `facadeforge points` run).
$(VENV)/.synced: $(UV) pyproject.toml uv.lock
	$(UV) sync --frozen --compile-bytecode --python $(PYTHON)
	$(VENV)/bin/python -m compileall -q src
	touch $@

env: $(VENV)/.synced

# PyTorch for training the convnet classifier, in its own environment so `make test` stays light.
train-env: $(UV) pyproject.toml uv.lock
	UV_PROJECT_ENVIRONMENT=.venv-train $(UV) sync --frozen --extra train --python $(PYTHON)

# Open3D (large) for benchmarks/planes.py, in its own environment: `make env` never installs it.
# Its wheel also needs the system's libusb-1.0 (Debian: apt-get install libusb-1.0-0).
bench-env: $(UV) pyproject.toml uv.lock
	UV_PROJECT_ENVIRONMENT=.venv-bench $(UV) sync --frozen --group bench --python $(PYTHON)

# Esri's PyPRT (free for non-commercial use; never a dependency of facadeforge) for
# benchmarks/vs_prt.py, in its own environment holding nothing else.
prt-env: $(UV) pyproject.toml uv.lock
	UV_PROJECT_ENVIRONMENT=.venv-prt $(UV) sync --frozen --only-group prt --no-install-project --python $(PYTHON)

demo: env
	$(VENV)/bin/facadeforge demo -o demo-out

lint: env
	$(VENV)/bin/ruff check src tests benchmarks docs

test: env lint docs gltf-validator cjval
	$(VENV)/bin/python -m pytest

# The Khronos glTF validator (npm's gltf-validator, pinned in tests/gltf/package-lock.json) for
# tests/exchange/test_gltf_valid.py, into tests/gltf/node_modules.  Without npm, or offline,
# `make test` goes on and those tests skip, saying why.
GLTF_VALIDATOR := tests/gltf/node_modules/gltf-validator/package.json
gltf-validator:
	@if [ -f $(GLTF_VALIDATOR) ]; then :; \
	elif command -v npm >/dev/null 2>&1; then \
		(cd tests/gltf && npm ci --no-audit --no-fund --silent) || \
			echo "gltf-validator: npm ci failed; the glTF validation tests will skip"; \
	else echo "gltf-validator: npm not found; the glTF validation tests will skip"; fi

# The documentation site (MkDocs, Material, mkdocstrings; mkdocs.yml) from docs/ into site/, in
# its own environment .venv-docs holding only the docs group (the API reference is read from
# src/ without importing it).  --strict: any warning (a broken link, a missing page, a
# docstring mkdocstrings cannot read) fails the build.  Offline: no fonts or CDN fetched
# (theme.font: false); the benchmark pages are written from benchmarks/results/*.json by the
# hook docs/hooks/bench_pages.py at build time.  Not --quiet: it hides the warnings --strict counts.
DOCS_VENV := .venv-docs
$(DOCS_VENV)/.synced: $(UV) pyproject.toml uv.lock
	UV_PROJECT_ENVIRONMENT=$(DOCS_VENV) $(UV) sync --frozen --only-group docs --no-install-project --python $(PYTHON)
	touch $@

docs: $(DOCS_VENV)/.synced
	NO_MKDOCS_2_WARNING=1 $(DOCS_VENV)/bin/mkdocs build --strict

# The long fuzz run (tests/fuzz): mutated rules, footprints, classifiers, rule packages and
# models until FUZZ_SECONDS are spent, each run bounded to 60 s and 3 GiB; FUZZ_SEED for others.
FUZZ_SECONDS ?= 600
FUZZ_SEED ?= 20261201
fuzz: env
	FACADEFORGE_FUZZ=long FACADEFORGE_FUZZ_SECONDS=$(FUZZ_SECONDS) FACADEFORGE_FUZZ_SEED=$(FUZZ_SEED) \
		$(VENV)/bin/python -m pytest tests/fuzz -q -s -p no:cacheprovider

# three.js for the editor and viewer pages, from npm (web/package-lock.json), bundled by esbuild
# into src/facadeforge/editor/static/vendor/three.bundle.js.  The bundle is committed, so the
# package works offline and `make test` needs no npm; rerun this after changing web/.
web:
	cd web && npm ci --no-audit --no-fund && node build.mjs

# The README's editor and viewer pictures, taken by the browser tests (tests/editor/test_browser.py)
# in headless Chromium.
screenshots: env
	FACADEFORGE_SCREENSHOTS=$(CURDIR)/docs/images $(VENV)/bin/python -m pytest tests/editor/test_browser.py -q

bench: env
	$(VENV)/bin/python benchmarks/engine.py
	$(VENV)/bin/python benchmarks/report.py

# cjval, the official CityJSON validator (crates.io, pinned, its Cargo.lock kept: --locked) for
# the tests that validate our CityJSON and CityJSONSeq files (tests/cjval.py), into .tools/cjval.
# A debug build: it compiles in about a minute on two cores instead of 10, and checks our small
# test files as well.  Without cargo (https://rustup.rs) `make test` goes on and those tests skip.
CJVAL_VERSION := 0.10.0
CARGO ?= $(shell command -v cargo || echo $(HOME)/.cargo/bin/cargo)
CJVAL := $(TOOLS)/cjval/bin/cjval
cjval:
	@if [ -x $(CJVAL) ]; then :; \
	elif [ -x "$(CARGO)" ]; then \
		$(CARGO) install cjval --version $(CJVAL_VERSION) --features build-binary --locked --debug \
			--quiet --root $(TOOLS)/cjval || \
			echo "cjval: cargo install failed; the CityJSON validation tests will skip"; \
	else echo "cjval: cargo not found; the CityJSON validation tests will skip"; fi

clean:
	rm -rf $(VENV) .venv-train .venv-bench .venv-prt .venv-docs site $(TOOLS) .pytest_cache .ruff_cache
