"""MkDocs hook: the benchmark pages, written from ``benchmarks/results/*.json`` at build time.

Nothing on these pages is typed by hand: every figure is read from a results file, and every
table says which file, machine, date and commit it comes from.  The pages exist only in the
build (``results/…`` in the site); the raw files are copied beside them (``results/data/``).

The same hook turns links from the docs to files of the repository outside ``docs/`` (source
files, benchmark scripts: right on GitHub, not part of the site) into their repository path,
so that ``mkdocs build --strict`` still fails on a link to a page that does not exist.

``pages(results_dir)`` is plain Python (the tests call it without MkDocs installed).
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"

#: Result files whose long lists are per-item detail: summarised, not tabulated.
_MAX_ROWS = 40
#: Keys that say where and when a result was measured (shown once, not as figures).
_PROVENANCE = ("machine", "date", "commit")


# ---------------------------------------------------------------------------- formatting


def _num(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}"
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        return format(v, ".6g")
    return _text(v)


def _text(v) -> str:
    if v is None:
        return "–"
    s = " ".join(str(v).split())
    if len(s) > 160:
        s = s[:157] + "…"
    for ch in "\\`*_[]<>|":
        s = s.replace(ch, "\\" + ch)
    return s


def _is_scalar(v) -> bool:
    return v is None or isinstance(v, (str, int, float, bool))


def _short_list(v) -> bool:
    return isinstance(v, list) and len(v) <= 8 and all(_is_scalar(x) for x in v)


def _cell(v) -> str:
    if _short_list(v):
        return ", ".join(_num(x) for x in v)
    return _num(v)


def machine_text(m, r: dict | None = None) -> str:
    """``2 cores (AMD EPYC), 23.5 GiB, Python 3.11.7`` from a results file's ``machine``."""
    if isinstance(m, dict):
        parts = [f"{m['cores']} cores" if "cores" in m else None,
                 f"({m['cpu']})" if m.get("cpu") else None]
        head = " ".join(p for p in parts if p) or "machine"
        tail = [f"{m['memory_gib']} GiB" if "memory_gib" in m else None,
                f"Python {m['python']}" if m.get("python") else None]
        return ", ".join([head] + [t for t in tail if t])
    if m is None:
        return "machine not recorded"
    cores = (r or {}).get("cores")
    return f"{cores} cores ({m})" if cores else str(m)


def provenance(r: dict, name: str) -> str:
    """One line: where the figures of ``r`` (the file ``name``) were measured."""
    link = f"[`{name}`](data/{name})"
    own = [(p, x) for p, x in _measurements(r)]
    if not own:
        return f"From {link}; the file records no machine, date or commit."
    lines = []
    for path, x in own:
        where = f"{path}: " if path else ""
        date = str(x.get("date", "date not recorded"))[:10]
        commit = f"commit `{x['commit']}`" if x.get("commit") else "commit not recorded"
        mach = x.get("machine", r.get("machine"))
        lines.append(f"{where}measured {date} at {commit} on {machine_text(mach, r)}")
    if len(lines) == 1:
        return f"From {link}; {lines[0]}."
    return f"From {link}:\n\n" + "\n".join(f"- {line}" for line in lines)


def _measurements(r, path: str = ""):
    """(where, dict) for ``r`` and every nested dict that records its own date or commit."""
    if not isinstance(r, dict):
        return
    if "commit" in r or "date" in r:
        yield path, r
    for k, v in r.items():
        if isinstance(v, dict):
            yield from _measurements(v, f"{path}.{k}" if path else k)
        elif isinstance(v, list) and len(v) <= 8:
            for i, x in enumerate(v):
                yield from _measurements(x, f"{path}.{k}[{i}]" if path else f"{k}[{i}]")


def _flat(d: dict, prefix: str = "", depth: int = 2) -> dict:
    """The scalar leaves of ``d`` (and of its dicts, ``depth`` levels down) as dotted keys."""
    out = {}
    for k, v in d.items():
        if k in _PROVENANCE and not prefix:
            continue
        key = f"{prefix}{k}"
        if _is_scalar(v) or _short_list(v):
            out[key] = v
        elif isinstance(v, dict) and depth > 0:
            out.update(_flat(v, key + ".", depth - 1))
    return out


def table(rows: list[tuple[str, dict]], first: str = "") -> str:
    """A markdown table: one row per (name, flat dict), one column per key."""
    cols: list[str] = []
    for _, d in rows:
        cols += [c for c in d if c not in cols]
    head = f"| {_text(first)} | " + " | ".join(_text(c) for c in cols) + " |"
    sep = "|---" * (len(cols) + 1) + "|"
    body = [f"| {_text(name)} | " + " | ".join(_cell(d[c]) if c in d else "–" for c in cols)
            + " |" for name, d in rows]
    return "\n".join([head, sep, *body])


def generic(r, title: str = "", level: int = 0) -> str:
    """Every figure of a results file, as tables: scalars as a key/value table, a dict of
    records (or a short list of records) as one table, anything longer summarised."""
    out = []
    if isinstance(r, list):
        if len(r) <= _MAX_ROWS and all(isinstance(x, dict) for x in r):
            return table([(str(i), _flat(x)) for i, x in enumerate(r)], "#")
        return f"{len(r):,} entries: see the file."
    scalars = {k: v for k, v in r.items()
               if k not in _PROVENANCE and (_is_scalar(v) or _short_list(v))}
    if scalars:
        out.append("| key | value |\n|---|---|\n"
                   + "\n".join(f"| {_text(k)} | {_cell(v)} |" for k, v in scalars.items()))
    records = {k: v for k, v in r.items()
               if isinstance(v, dict) and v and all(isinstance(x, dict) for x in v.values())
               and all(_flat(x) for x in v.values())}
    for k, v in r.items():
        if k in scalars or k in _PROVENANCE:
            continue
        label = f"**{_text(f'{title}.{k}' if title else k)}**"
        if k in records:
            out.append(f"{label}\n\n" + table([(n, _flat(x)) for n, x in v.items()]))
        elif isinstance(v, dict):
            if level >= 3:
                out.append(f"{label}: {len(v)} entries: see the file.")
            else:
                inner = generic(v, f"{title}.{k}" if title else k, level + 1)
                if inner:
                    out.append(f"{label}\n\n{inner}")
        elif isinstance(v, list):
            if v and len(v) <= _MAX_ROWS and all(isinstance(x, dict) for x in v):
                out.append(f"{label}\n\n" + table([(str(i), _flat(x)) for i, x in enumerate(v)],
                                                  "#"))
            else:
                out.append(f"{label}: {len(v):,} entries: see the file.")
    return "\n\n".join(out)


# ---------------------------------------------------------------------------- the pages


def _load(results: Path, name: str):
    path = results / name
    return json.loads(path.read_text(encoding="utf-8")) if path.exists() else None


def _report_module(results: Path):
    """``benchmarks/report.py``: the README's tables, so the site and the README agree."""
    path = results.parent / "report.py"
    spec = importlib.util.spec_from_file_location("_facadeforge_bench_report", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.ROOT = results.parents[1]   # read the same results folder as the pages
    return mod


def _section(results: Path, name: str, title: str, intro: str = "", body: str | None = None,
             used: set | None = None, own_provenance: bool = False) -> str:
    """A page section for the results file ``name``: its provenance, then ``body`` (default:
    every figure of the file); ``own_provenance``: the body already says where it was
    measured."""
    r = _load(results, name)
    if r is None:
        return ""
    if used is not None:
        used.add(name)
    text = generic(r) if body is None else body
    where = provenance(r, name) if isinstance(r, dict) else ""
    if own_provenance:
        where = f"From [`{name}`](data/{name})."
    parts = [f"## {title}", intro, where, text]
    return "\n\n".join(p for p in parts if p)


def _per_class(results: Path) -> str:
    """Per-class accuracy (the confusion matrices' diagonals) of every ``bench_*`` method,
    and of ``classifiers.json``'s forests, per dataset."""
    out = []
    by_dataset: dict[str, list] = {}
    for path in sorted(results.glob("bench_*.json")):
        r = json.loads(path.read_text(encoding="utf-8"))
        if not r.get("confusion_percent"):
            continue
        by_dataset.setdefault(r["dataset"], []).append((path.name, r))
    forests = (_load(results, "classifiers.json") or {}).get("results", {})
    for dataset, runs in sorted(by_dataset.items()):
        classes = runs[0][1]["classes"]
        rows = []
        for _name, r in runs:
            if r["classes"] != classes:
                continue
            diag = [r["confusion_percent"][i][i] for i in range(len(classes))]
            rows.append(f"| {_text(r['method'])} ({_text(r['split'])}, {r['n_images']}) | "
                        + " | ".join(f"{d:.0f}" for d in diag)
                        + f" | {100 * r['class_avg_accuracy']:.1f} | "
                        f"{r['date'][:10]} `{r['commit']}` |")
        f = forests.get(dataset, {})
        for method, v in f.items():
            acc = v.get("per_class_accuracy") if isinstance(v, dict) else None
            if acc and list(acc) == list(classes):
                rows.append(f"| {_text(method)} (`classifiers.json`, {f.get('val_images')}) | "
                            + " | ".join(f"{100 * acc[c]:.0f}" for c in classes)
                            + f" | {100 * v['class_avg_accuracy']:.1f} | see below |")
        out.append(f"**{_text(dataset)} ({_text(runs[0][1]['label_set'])})**, per-class accuracy "
                   f"%:\n\n| method | {' | '.join(_text(c) for c in classes)} | class-avg | "
                   f"measured |\n|---|{'---|' * (len(classes) + 2)}\n" + "\n".join(rows))
    return "\n\n".join(out)


def _points_summary(r: dict) -> str:
    rows = []
    for key in ("nuist", "nuist_grammar", "synthetic", "synthetic_grammar", "synthetic_dev"):
        v = r.get(key)
        if not isinstance(v, dict) or "model" not in v:
            continue
        m = v["model"]
        pts = v.get("points", sum(s.get("points", 0) for s in v.get("scans", [])))
        eq = v.get("eq_5_10_cm", {}).get("cm")
        rows.append(f"| {key} | {pts:,} | {m['precision']:.2f} / {m['recall']:.2f} / "
                    f"{m['f1']:.2f} | {'–' if eq is None else f'{eq:.1f} cm'} | "
                    f"{v['seconds']:.1f} s |" if "seconds" in v else
                    f"| {key} | {pts:,} | {m['precision']:.2f} / {m['recall']:.2f} / "
                    f"{m['f1']:.2f} | {'–' if eq is None else f'{eq:.1f} cm'} | – |")
    for key in ("lille", "million", "street"):
        v = r.get(key)
        if isinstance(v, dict) and "cli_seconds" in v:
            rows.append(f"| {key} | {v['points']:,} | – | – | {v['cli_seconds']:.1f} s (whole CLI) |")
    return ("| scan | points | windows and doors P / R / F1 (IoU ≥ 0.5) | eq. 5.10 | time |\n"
            "|---|---|---|---|---|\n" + "\n".join(rows))


def _planes_summary(r: dict) -> str:
    rows = []
    for cloud, v in r.get("clouds", {}).items():
        for method, m in v.get("methods", {}).items():
            n = m.get("planes_per_run") or []
            rows.append(f"| {_text(cloud)} | {v['points']:,} | {_text(method)} | "
                        f"{m['seconds']:.3f} s | {', '.join(str(x) for x in sorted(set(n)))} |")
    return ("| cloud | points | method | seconds (best of runs) | planes |\n"
            "|---|---|---|---|---|\n" + "\n".join(rows))


def _cli_speed(r: dict) -> str:
    rows = [f"| `{_text(x['command'])}` | {_text(x.get('photo'))} {_text(x.get('pixels', ''))} | "
            f"{x['first_s']:.2f} s | {x['median_s']:.2f} s |" for x in r.get("rows", [])]
    return ("| command | photo | first run | median of the later runs |\n|---|---|---|---|\n"
            + "\n".join(rows))


def _hostile(r: dict) -> str:
    side = next(iter(r.get("side_by_side", {}).values()), {})
    rows = []
    for case, c in r.get("cases", {}).items():
        b = side.get(case, {})
        rows.append(f"| {_text(case)} | {_cell(r['within_60s_3GB'].get(case))} | {c['rc']} | "
                    f"{c['seconds']:.1f} s | {c.get('peak_mib', '–')} MiB | "
                    f"{_cell(b.get('rc'))} | {_cell(b.get('seconds'))} s |")
    return ("| reproducer | within 60 s and 3 GB | exit code | seconds | peak memory | "
            "before: exit code | before: seconds |\n|---|---|---|---|---|---|---|\n"
            + "\n".join(rows))


def pages(results: Path = RESULTS) -> dict[str, str]:
    """``{site path: markdown}`` of the benchmark pages, from the files in ``results``."""
    report = _report_module(results)
    used: set[str] = set()
    note = ("*Generated at build time from `benchmarks/results/*.json` by "
            "`docs/hooks/bench_pages.py`; nothing on this page is typed by hand.  How each "
            "benchmark is run, and the history of earlier figures: "
            "[Benchmark notes and history](../benchmarks.md).*")

    def page(title: str, sections: list[str]) -> str:
        return "\n\n".join([f"# {title}", note, *[s for s in sections if s]]) + "\n"

    out = {}
    out["results/engine.md"] = page("Benchmarks: the CGA engine", [
        _section(results, "engine.json", "Engine benchmark (`make bench`)",
                 "The whole CLI process deriving `benchmarks/grammars/detailed.cga` on 40 "
                 "footprints, one export format at a time.",
                 report.engine_table(), used, own_provenance=True),
        _section(results, "engine_varied.json", "The same building with a random choice per "
                 "window", used=used),
        _section(results, "engine_budget_overhead.json", "Cost of the derivation limits",
                 used=used),
        _section(results, "engine_city.json", "A city: 200 buildings in one file", used=used),
        _section(results, "occlusion.json", "Occlusion queries", used=used),
        _section(results, "cleanup.json", "cleanupGeometry", used=used),
        _section(results, "cga_speed.json", "Speed on other people's rules", used=used),
        _section(results, "cga_speed_2026-12-01.json", "Speed on other people's rules: "
                 "the heaviest files again", used=used),
        _section(results, "hostile.json", "Hostile input",
                 "Every reproducer of `benchmarks/hostile.py` as a whole CLI process; "
                 "`before`: the code before the limits.", _hostile(_load(results, "hostile.json")
                                                                   or {}), used),
    ])
    survey = _load(results, "cga_survey.json") or {}
    out["results/cga.md"] = page("Benchmarks: CityEngine rule files", [
        _section(results, "cga_survey.json", "Compatibility survey",
                 "Public CityEngine rule files, each loaded and derived on a 20 × 15 m lot.",
                 generic({k: v for k, v in survey.items() if k != "per_file"}), used),
        _section(results, "cga_sweep.json", "Robustness sweep: every choice, odd lots",
                 used=used),
    ])
    out["results/labelling.md"] = page("Benchmarks: facade labelling and parsing", [
        "## Every method (`facadeforge bench`)\n\n" + report.methods_table(),
        "## Per-class accuracy\n\nThe diagonals of each run's confusion matrix "
        "(`confusion_percent`).\n\n" + _per_class(results),
        "## The runs\n\n" + "\n".join(
            "- " + provenance(json.loads(p.read_text(encoding="utf-8")), p.name)
            for p in sorted(results.glob("bench_*.json"))),
        _section(results, "classifiers.json", "Pixel classifiers", used=used),
        _section(results, "detect_cmp.json", "Element detection, step by step", used=used),
        _section(results, "evidence.json", "How much the grammar may overrule the classifier",
                 used=used),
        _section(results, "parsing_curves.json", "Hill climbing against the evolutionary search",
                 "Mean best energy per pixel over the validation facades at equal budget; the "
                 "curves themselves are in the file and in the figure of the notes.",
                 used=used),
    ])
    used.update(p.name for p in results.glob("bench_*.json"))
    cli = _load(results, "cli_speed.json") or {}
    out["results/reconstruct.md"] = page("Benchmarks: photo → procedural facade", [
        _section(results, "cli_speed.json", "What a user waits for",
                 "Whole CLI processes, every OUTDIR file written.", _cli_speed(cli), used),
        _section(results, "reconstruct.json", "reconstruct on synthetic facades", "",
                 report.reconstruct_table() + "\n\n"
                 + generic({k: v for k, v in (_load(results, "reconstruct.json") or {}).items()
                            if k != "facades"}), used),
        _section(results, "symmetry.json", "Stage 1: symmetry", used=used),
    ])
    pts = _load(results, "points.json") or {}
    planes = _load(results, "planes.json") or {}
    out["results/points.md"] = page("Benchmarks: laser scans", [
        _section(results, "points.json", "facadeforge points", "",
                 _points_summary(pts) + "\n\n" + generic(pts), used),
        _section(results, "planes.json", "Planes: facadeforge against Open3D", "",
                 _planes_summary(planes), used),
        _section(results, "points_store.json", "Point store", used=used),
    ])
    rep = _load(results, "repair.json") or {}
    out["results/repair.md"] = page("Benchmarks: texture repair", [
        _section(results, "repair.json", "Repair of pasted occluders", "",
                 report.repair_table() + "\n\n"
                 + generic({k: v for k, v in rep.items() if k in ("protocol", "paper")}), used),
        _section(results, "synthesis.json", "Label → image synthesis", used=used),
    ])
    rest = [p.name for p in sorted(results.glob("*.json")) if p.name not in used]
    if rest:
        out["results/other.md"] = page("Benchmarks: other results",
                                       [_section(results, n, f"`{n}`", used=used) for n in rest])
    out["results/index.md"] = _index(results, out)
    return out


def _index(results: Path, out: dict[str, str]) -> str:
    """The overview: the headline tables and every results file with its provenance."""
    report = _report_module(results)
    where = {}
    for path, text in out.items():
        for name in re.findall(r"\(data/([^)]+\.json)\)", text):
            where.setdefault(name, path.removeprefix("results/"))
    rows = []
    for p in sorted(results.glob("*.json")):
        r = json.loads(p.read_text(encoding="utf-8"))
        ms = list(_measurements(r)) if isinstance(r, dict) else []
        dates = sorted({str(x.get("date"))[:10] for _, x in ms if x.get("date")})
        commits = sorted({str(x.get("commit")) for _, x in ms if x.get("commit")})
        machines = sorted({machine_text(x.get("machine", r.get("machine")), r) for _, x in ms})
        page = where.get(p.name)
        rows.append(f"| [`{p.name}`](data/{p.name}) | {', '.join(dates) or '–'} | "
                    f"{', '.join(f'`{c}`' for c in commits) or '–'} | "
                    f"{_text('; '.join(machines)) or '–'} | "
                    f"{f'[{page[:-3]}]({page})' if page else '–'} |")
    eng = _load(results, "engine.json")
    summary = report.methods_table(report.SUMMARY_METHODS)
    text = [
        "# Benchmarks",
        "*Generated at build time from `benchmarks/results/*.json` by "
        "`docs/hooks/bench_pages.py`; nothing on these pages is typed by hand.  Each table "
        "names the file, machine, date and commit of its figures.  How the benchmarks are "
        "run and what earlier figures were: [Benchmark notes and history](../benchmarks.md).*",
        "Pages: [the CGA engine](engine.md) · [CityEngine rule files](cga.md) · "
        "[facade labelling and parsing](labelling.md) · [photo → procedural facade]"
        "(reconstruct.md) · [laser scans](points.md) · [texture repair](repair.md)"
        + (" · [other results](other.md)" if "results/other.md" in out else ""),
    ]
    if eng:
        text.append("## The engine\n\n" + provenance(eng, "engine.json") + "\n\n"
                    + report.engine_table())
    text.append("## Facade labelling (current methods)\n\n" + summary)
    if (results / "repair.json").exists():
        text.append("## Texture repair\n\n" + report.repair_table())
    text.append("## Every results file\n\n| file | measured | commit | machine | page |\n"
                "|---|---|---|---|---|\n" + "\n".join(rows))
    return "\n\n".join(text) + "\n"


# ---------------------------------------------------------------------------- MkDocs events

_LINK = re.compile(r"(!?)\[([^\]\n]*)\]\(([^)\s]+)\)")


def outside_links(markdown: str, page_dir: Path, docs_dir: Path, root: Path = ROOT,
                  repo_url: str | None = None) -> str:
    """Links to repository files outside ``docs_dir`` → the file's repository path (a link
    to it on ``repo_url`` when the site has one).  Links to missing files are left alone, so
    the build still warns about them."""
    def sub(m: re.Match) -> str:
        bang, text, target = m.groups()
        if bang or re.match(r"[a-z][a-z0-9+.-]*:|#|/", target):
            return m.group(0)
        path, _, anchor = target.partition("#")
        dest = (page_dir / path).resolve()
        try:
            dest.relative_to(docs_dir.resolve())
            return m.group(0)          # a page or file of the site: MkDocs checks it
        except ValueError:
            pass
        try:
            rel = dest.relative_to(root.resolve()).as_posix()
        except ValueError:
            return m.group(0)
        if not dest.exists():
            return m.group(0)
        if dest.parent == RESULTS.resolve() and dest.suffix == ".json":   # copied into the site
            copy = docs_dir.resolve() / "results" / "data" / dest.name
            return f"[{text}]({Path(os.path.relpath(copy, page_dir.resolve())).as_posix()})"
        if repo_url:
            kind = "tree" if dest.is_dir() else "blob"
            return f"[{text}]({repo_url.rstrip('/')}/{kind}/main/{rel})"
        shown = text.strip("`")
        return text if shown == rel or shown.endswith(rel) else f"{text} (`{rel}`)"
    return _LINK.sub(sub, markdown)


def on_files(files, config):
    from mkdocs.structure.files import File

    for path, text in pages().items():
        files.append(File.generated(config, path, content=text))
    for p in sorted(RESULTS.glob("*.json")):
        files.append(File.generated(config, f"results/data/{p.name}", abs_src_path=str(p)))
    return files


def on_page_markdown(markdown, page, config, files):
    if page.file.generated_by:
        return markdown
    docs_dir = Path(config["docs_dir"])
    page_dir = (docs_dir / page.file.src_uri).parent
    return outside_links(markdown, page_dir, docs_dir, ROOT, config.get("repo_url"))
