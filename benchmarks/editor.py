"""What a user of ``facadeforge edit`` waits for, in a real browser (Debian's Chromium headless,
software WebGL, driven by Playwright): the page from its URL to ``window.facadeforge.ready``,
each edit from ``apply()`` to its resolved Promise (re-extracted rules, re-derived model, glTF
sent, parsed and drawn), and ``save()`` (the whole OUTDIR staged and swapped in).

Facades: a synthetic one (seed 29, ``residential``) and, when ``../shared/data`` has it, the CMP
val facade ``cmp_b0187``, both reconstructed first (not timed).  ``--repeats`` edits of each
kind, alternating signs so the facade stays the same.  JSON (machine, date, commit) to
``benchmarks/results/editor.json``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


def _outdirs(tmp: Path) -> dict[str, Path]:
    from facadeforge.datasets.synthetic import generate
    from facadeforge.reconstruction import reconstruct

    photo = generate(1, seed=29, out_dir=tmp / "photo", size=560, styles=["residential"])[0]
    meta = json.loads(photo.with_suffix(".meta.json").read_text())
    out = {"synthetic_residential": tmp / "synthetic"}
    reconstruct(photo, rectified=True, width_m=meta["facade_size_m"][0],
                out_dir=out["synthetic_residential"])
    if (DATA / "cmp").is_dir():
        from facadeforge.datasets import load_cmp

        (sample,) = [s for s in load_cmp(DATA / "cmp") if s.id == "cmp_b0187"]
        out["cmp_b0187"] = tmp / "cmp"
        reconstruct(sample.image(), rectified=True, out_dir=out["cmp_b0187"])
    return out


def _window(page) -> list[int]:
    return page.evaluate("""(() => {
        const stack = [[[], window.facadeforge.tree()]];
        while (stack.length) {
          const [p, n] = stack.pop();
          if (n.label === 'window' && !n.children.length) return p;
          n.children.forEach((c, i) => stack.push([p.concat([i]), c]));
        }
        return null; })()""")


def _stats(xs: list[float]) -> dict:
    xs = sorted(xs)
    return {"median_s": round(statistics.median(xs), 4),
            "p90_s": round(xs[min(len(xs) - 1, int(0.9 * len(xs)))], 4),
            "n": len(xs)}


def _measure(browser, outdir: Path, repeats: int) -> dict:
    from facadeforge.editor.server import editor_app, start
    from facadeforge.editor.session import EditSession

    t0 = time.perf_counter()
    session = EditSession(outdir)
    open_s = time.perf_counter() - t0
    srv = start(lambda token: editor_app(session, token))
    ctx = browser.new_context(viewport={"width": 1500, "height": 900})
    page = ctx.new_page()
    try:
        t0 = time.perf_counter()
        page.goto(srv.url)
        page.evaluate("window.facadeforge.ready")
        ready_s = time.perf_counter() - t0
        win = _window(page)
        times: dict[str, list[float]] = {"move_split": [], "set_depth": []}
        for k in range(repeats):
            sign = 1 if k % 2 == 0 else -1
            for op, edit in (("move_split", {"op": "move_split", "path": [], "index": 1,
                                             "delta": 0.3 * sign}),
                             ("set_depth", {"op": "set_depth", "path": win,
                                            "depth": -0.6 if sign > 0 else -0.25})):
                t0 = time.perf_counter()
                page.evaluate(f"window.facadeforge.apply({json.dumps(edit)})")
                times[op].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        page.evaluate("window.facadeforge.save()")
        save_s = time.perf_counter() - t0
        leaves = sum(1 for _ in session.tree.leaves())
        return {"open_session_s": round(open_s, 4), "page_ready_s": round(ready_s, 4),
                "edits": {op: _stats(v) for op, v in times.items()},
                "save_s": round(save_s, 4), "leaves": leaves,
                "derive_s_last": session.state()["derive_seconds"]}
    finally:
        ctx.close()
        srv.stop()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "editor.json"))
    args = ap.parse_args(argv)
    chromium = shutil.which("chromium")
    if chromium is None:
        raise SystemExit("needs Debian's chromium (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        outdirs = _outdirs(Path(tmp))
        browser = p.chromium.launch(executable_path=chromium, args=[
            "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--no-sandbox"])
        facades = {name: _measure(browser, d, args.repeats) for name, d in outdirs.items()}
        browser.close()
    result = {**provenance(), "browser": "Debian chromium headless, SwiftShader WebGL",
              "repeats": args.repeats, "facades": facades}
    save_result(result, args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
