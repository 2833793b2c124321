"""The docs site's benchmark pages (docs/hooks/bench_pages.py): written from the results files,
every file on a page with its provenance; links out of docs/ rewritten, broken ones kept."""

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def hook():
    spec = importlib.util.spec_from_file_location("bench_pages", ROOT / "docs/hooks/bench_pages.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_results_file_is_on_a_page():
    pages = hook().pages(RESULTS)
    assert "results/index.md" in pages
    text = "\n".join(v for k, v in pages.items() if k != "results/index.md")
    for p in RESULTS.glob("*.json"):
        assert f"(data/{p.name})" in text, f"{p.name} is on no benchmark page"
        assert f"(data/{p.name})" in pages["results/index.md"]


def test_pages_say_where_and_when(tmp_path):
    r = {"benchmark": "x", "speed": 1.25, "date": "2026-01-02T03:04:05+00:00", "commit": "abc1234",
         "machine": {"cpu": "Test CPU", "cores": 3, "memory_gib": 4.0, "python": "3.11.7"},
         "cases": {"a": {"seconds": 0.5}, "b": {"seconds": 7}}}
    results = tmp_path / "results"
    results.mkdir()
    (results / "x.json").write_text(json.dumps(r))
    h = hook()
    section = h._section(results, "x.json", "X")
    assert "measured 2026-01-02 at commit `abc1234` on 3 cores (Test CPU)" in section
    assert "| speed | 1.25 |" in section and "| a | 0.5 |" in section


def test_links_out_of_docs(tmp_path):
    h = hook()
    docs = ROOT / "docs"
    md = ("[engine](../benchmarks/engine.py) [gone](../benchmarks/gone.py) [page](gml.md) "
          "[data](../benchmarks/results/engine.json) [web](https://example.org/x)")
    out = h.outside_links(md, docs, docs, ROOT)
    assert "engine (`benchmarks/engine.py`)" in out
    assert "[gone](../benchmarks/gone.py)" in out          # missing: MkDocs --strict reports it
    assert "[page](gml.md)" in out and "[web](https://example.org/x)" in out
    assert "[data](results/data/engine.json)" in out
    linked = h.outside_links("[x](../src/facadeforge/cli.py)", docs, docs, ROOT,
                             repo_url="https://example.org/ff")
    assert linked == "[x](https://example.org/ff/blob/main/src/facadeforge/cli.py)"
