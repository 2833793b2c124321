"""Write the benchmark tables of README.md, docs/benchmarks.md and benchmarks/README.md from benchmarks/results/*.json.

Run after a benchmark: ``.venv/bin/python benchmarks/report.py``.  The tables sit between
``<!-- bench:engine -->`` markers so the text around them stays hand-written.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


_FORMAT_NAMES = {"glb": "GLB", "obj": "OBJ", "city.json": "CityJSON"}


def engine_table() -> str:
    path = ROOT / "benchmarks" / "results" / "engine.json"
    if not path.exists():
        return "_no result yet: run `make bench`_"
    r = json.loads(path.read_text())
    m = r["machine"]
    formats = r.get("formats") or {r.get("format", "glb"): r}
    names = [_FORMAT_NAMES.get(f, f) for f in formats]
    rows = [
        ("buildings / s (40 footprints, whole CLI process)",
         [f"{v['buildings_per_second']:.2f}" for v in formats.values()]),
        ("faces / s", [f"{v['faces_per_second']:,}" for v in formats.values()]),
        ("best wall time", [f"{v['best_wall_seconds']:.1f} s of {r['runs']} runs"
                            for v in formats.values()]),
        ("peak memory (largest process)",
         [f"{v['peak_memory_mib_per_process']:.0f} MiB" for v in formats.values()]),
    ]
    head = (f"Measured {r['date'][:10]} at commit `{r['commit']}` on {m['cores']} cores "
            f"({m['cpu']}), {m['memory_gib']} GiB, Python {m['python']}: "
            f"{r['faces_per_building']:,} faces a building, {r['warnings']} warnings.\n\n")
    table = (head + "| engine benchmark | " + " | ".join(names) + " |\n|---|"
             + "---|" * len(names) + "\n"
             + "\n".join(f"| {a} | " + " | ".join(b) + " |" for a, b in rows))
    for side, per_format in r.get("side_by_side", {}).items():
        table += (f"\n\nSide by side, runs alternating, buildings / s: `{side}` against this "
                  "commit\n\n| format | before | after |\n|---|---|---|\n"
                  + "\n".join(f"| {_FORMAT_NAMES.get(f, f)} | "
                              f"{per_format[f]['buildings_per_second']:.2f} | "
                              f"{formats[f]['buildings_per_second']:.2f} |" for f in formats))
    return table


#: The methods of the README's summary table (docs/benchmarks.md has them all).
SUMMARY_METHODS = ("classifier", "grammar", "multiview", "structure")


def methods_table(only: tuple[str, ...] | None = None) -> str:
    """Every ``results/bench_*.json`` (of the ``only`` methods): one row per method and
    dataset."""
    rows = []
    for path in sorted((ROOT / "benchmarks" / "results").glob("bench_*.json")):
        r = json.loads(path.read_text())
        if only is not None and r["method"] not in only:
            continue

        def f(key, r=r):
            v = r.get(key)
            return "–" if v is None else f"{v:.3f}"
        rows.append(f"| {r['method']} | {r['dataset']} ({r['split']}, {r['label_set']}) | "
                    f"{r['n_images']} | {f('pixel_accuracy')} | {f('class_avg_accuracy')} | "
                    f"{f('miou')} | {f('window_f1')} | {r['seconds_per_image']:.3f} | "
                    f"{r['date'][:10]} `{r['commit']}` |")
    if not rows:
        return "_no result yet_"
    head = ("| method | dataset | images | pixel acc | class-avg acc | mIoU | window F1 | s / image "
            "| measured |\n|---|---|---|---|---|---|---|---|---|\n")
    return head + "\n".join(rows)


def reconstruct_table() -> str:
    path = ROOT / "benchmarks" / "results" / "reconstruct.json"
    if not path.exists():
        return "_no result yet: run `.venv/bin/python benchmarks/reconstruct.py`_"
    r = json.loads(path.read_text())
    m = r["machine"]
    head = (f"Measured {r['date'][:10]} at commit `{r['commit']}` on {m['cores']} cores "
            f"({m['cpu']}), best of {r['runs']} warm runs, every OUTDIR file written.\n\n"
            "| facade (synthetic) | pixels | reconstruct | stage 1 (symmetry) | floors | tiles "
            "| window P / R / F1 |\n|---|---|---|---|---|---|---|\n")
    rows = [f"| {f['style']} | {f['size'][0]}×{f['size'][1]} | {f['seconds']:.2f} s | "
            f"{f['timings']['symmetry']:.3f} s | {f['floors']} | {f['tiles']} | "
            f"{f['window_precision']:.2f} / {f['window_recall']:.2f} / {f['window_f1']:.2f} |"
            for f in r["facades"]]
    return head + "\n".join(rows)


# Per-class accuracy (%) on the Ecole Centrale Paris facades, simon2011 §4.3.1 (randomised forest
# alone) and §4.4.1 (grammar-driven parsing), 10 test facades, classes in ecp7 order.
THESIS_ECP = {
    "simon2011 RF (ECP, §4.3.1)": (30, 62, 48, 81, 57, 89, 40),
    "simon2011 grammar (ECP, §4.4.1)": (81, 83, 72, 71, 80, 94, 95),
}


def parsing_table() -> str:
    """Per-class accuracy (confusion diagonals) of the parsing methods beside the thesis."""
    res = ROOT / "benchmarks" / "results"
    out = []
    for dataset, label_set in (("ruemonge", "ecp7"), ("cmp", "cmp6")):
        rows, classes = [], None
        if dataset == "ruemonge":
            classes = ("window", "wall", "balcony", "door", "roof", "sky", "shop")
            for name, acc in THESIS_ECP.items():
                rows.append(f"| {name} | " + " | ".join(str(a) for a in acc)
                            + f" | {sum(acc) / len(acc):.1f} |")
        forest = res / "classifiers.json"
        if forest.exists():
            f = json.loads(forest.read_text())["results"].get(dataset)
            if f:
                r = f["forest (§4.3.1)"]
                acc = r["per_class_accuracy"]
                classes = tuple(acc)
                rows.append(f"| forest §4.3.1, ours ({dataset} val, {f['val_images']}) | "
                            + " | ".join(f"{100 * acc[c]:.0f}" for c in classes)
                            + f" | {100 * r['class_avg_accuracy']:.1f} |")
        for method in ("classifier", "mrf", "grammar-hill", "grammar", "multiview"):
            path = res / f"bench_{method}_{dataset}.json"
            if not path.exists():
                continue
            r = json.loads(path.read_text())
            classes = tuple(r["classes"])
            diag = [r["confusion_percent"][i][i] for i in range(len(classes))]
            rows.append(f"| {method} ({dataset} {r['split']}, {r['n_images']}) | "
                        + " | ".join(f"{d:.0f}" for d in diag)
                        + f" | {100 * r['class_avg_accuracy']:.1f} |")
        if rows and classes:
            out.append(f"{dataset} ({label_set}), per-class accuracy %:\n\n"
                       f"| method | {' | '.join(classes)} | class-avg |\n"
                       f"|---|{'---|' * (len(classes) + 1)}\n" + "\n".join(rows))
    for name, what in (("classifiers.json", "`forest §4.3.1, ours` rows"),
                       ("parsing_curves.json", "energy curves below")):
        path = res / name
        if path.exists():
            r = json.loads(path.read_text())
            m = r["machine"]
            out.append(f"{what}: measured {r['date'][:10]} at commit `{r['commit']}` on "
                       f"{m['cores']} cores ({m['cpu']}), Python {m['python']}.")
    return "\n\n".join(out) if out else "_no result yet_"


def repair_table() -> str:
    """``results/repair.json``: masked and whole-image PSNR / SSIM per method."""
    path = ROOT / "benchmarks" / "results" / "repair.json"
    if not path.exists():
        return "_no result yet: run `benchmarks/repair.py`_"
    r = json.loads(path.read_text())
    m = r["machine"]
    rows = []
    for name, v in r["methods"].items():
        mean = v.get("mean")
        if not mean:
            continue
        mask = "true" if v.get("uses_true_mask") else ("–" if name == "none" else "found")
        if v.get("measured"):          # kept from an earlier run (benchmarks/repair.py --keep)
            name = f"{name} (at `{v['measured']['commit']}`)"
        rows.append(f"| {name} | {mask} | {mean['masked_psnr']:.2f} | {mean['masked_ssim']:.3f} "
                    f"| {mean['psnr']:.2f} | {mean['ssim']:.3f} | {mean['seconds']:.1f} |")
    n = next(iter(r["methods"].values())).get("n", "?")
    head = (f"{n} CMP val facades with LabelMeFacade test cars and trees pasted in front; "
            f"measured {r['date'][:10]} at `{r['commit']}` on {m['cores']} cores ({m['cpu']}).\n\n"
            "| method | mask | masked PSNR | masked SSIM | PSNR | SSIM | s / image |\n"
            "|---|---|---|---|---|---|---|\n")
    return head + "\n".join(rows)


def vs_prt_table() -> str:
    """Esri's runtime (PyPRT) and facadeforge on the same rule package and initial shapes,
    whole processes alternating (benchmarks/vs_prt.py)."""
    path = ROOT / "benchmarks" / "results" / "vs_prt.json"
    if not path.exists():
        return "_no result yet: run `make prt-env` and `benchmarks/vs_prt.py`_"
    r = json.loads(path.read_text())
    m, made = r["machine"], r["made"]
    rate, wall, peak = r["buildings_per_second"], r["wall_seconds"], r["peak_memory_mib"]
    head = (f"Measured {r['date'][:10]} at commit `{r['commit']}` on {m['cores']} cores "
            f"({m['cpu']}): `{r['rules']}` on {r['initial_shapes']}, GLB out, whole processes "
            f"alternating, best of {r['runs']} runs.  **facadeforge / PRT = {r['ratio']:.2f}×**\n\n")
    rows = [("buildings / s", f"{rate['prt']:.2f}", f"{rate['facadeforge']:.2f}"),
            ("wall seconds (each run)", ", ".join(f"{x:.1f}" for x in wall["prt"]),
             ", ".join(f"{x:.1f}" for x in wall["facadeforge"])),
            ("peak memory", f"{peak['prt']:,} MiB", f"{peak['facadeforge']:,} MiB"),
            ("faces made", f"{made['prt']['faces']:,}", f"{made['facadeforge']['faces']:,}"),
            ("area made", f"{made['prt']['area']:,.0f} m²", f"{made['facadeforge']['area']:,.0f} m²")]
    return (head + "| | PyPRT (Esri's runtime) | facadeforge |\n|---|---|---|\n"
            + "\n".join(f"| {a} | {b} | {c} |" for a, b, c in rows))


def editor_table() -> str:
    """What a user of ``facadeforge edit`` waits for in headless Chromium (benchmarks/editor.py)."""
    path = ROOT / "benchmarks" / "results" / "editor.json"
    if not path.exists():
        return "_no result yet: run `benchmarks/editor.py`_"
    r = json.loads(path.read_text())
    m = r["machine"]
    head = (f"Measured {r['date'][:10]} at commit `{r['commit']}` on {m['cores']} cores "
            f"({m['cpu']}), {r['browser']}; medians of {r['repeats']} edits.\n\n")
    rows = []
    for name, f in r["facades"].items():
        e = f["edits"]
        rows.append(f"| {name} ({f['leaves']} leaves) | {f['page_ready_s']:.2f} s | "
                    f"{e['move_split']['median_s']:.2f} s | {e['set_depth']['median_s']:.2f} s | "
                    f"{f['save_s']:.2f} s |")
    return (head + "| facade | page ready | move a split line | set a cluster's depth | save |\n"
            "|---|---|---|---|---|\n" + "\n".join(rows))


def city_table() -> str:
    """``batch`` on a synthetic city against the plain ``derive`` (benchmarks/city.py)."""
    path = ROOT / "benchmarks" / "results" / "city.json"
    if not path.exists():
        return "_no result yet: run `benchmarks/city.py`_"
    r = json.loads(path.read_text())
    m = r["machine"]
    bps, sec, mem = r["buildings_per_s"], r["seconds"], r["peak_memory_mib"]
    head = (f"Measured {r['date'][:10]} at commit `{r['commit']}` on {m['cores']} cores "
            f"({m['cpu']}): `{r['rules']}` on {r['footprints']:,} footprints, "
            f"{r['workers']} workers, {r['chunk']} buildings a chunk, whole CLI processes "
            f"(load average at start {r['load_average_at_start'][0]}).\n\n")
    rows = [f"| `batch` (Dask, local cluster) | {bps['batch']:.2f} | {sec['batch']:.0f} s | "
            f"{mem['batch_driver']:.0f} MiB | {mem['batch_largest_worker']:.0f} MiB |",
            f"| `derive` (process pool) | {bps['derive']:.2f} | {sec['derive']:.0f} s | "
            f"{mem['derive_main']:.0f} MiB | {mem['derive_largest_worker']:.0f} MiB |"]
    if bps.get("batch_killed_worker") is not None:
        rows.append(f"| `batch`, a worker killed midway | {bps['batch_killed_worker']:.2f} | "
                    f"{sec['batch_killed_worker']:.0f} s | | |")
    once = all(v for v in r["every_building_once"].values() if v is not None)
    tail = (f"\n\nEvery building exactly once in the chunks: {'yes' if once else 'NO'}; "
            f"a rerun with every chunk kept: {sec['batch_resume_all_kept']:.1f} s.")
    return (head + "| | buildings / s | wall time | peak memory, driver | peak memory, "
            "largest worker |\n|---|---|---|---|---|\n" + "\n".join(rows) + tail)


def enhance_table() -> str:
    """``enhance`` on textured mass models: windows found against the textures' (benchmarks/
    enhance.py)."""
    path = ROOT / "benchmarks" / "results" / "enhance.json"
    if not path.exists():
        return "_no result yet: run `benchmarks/enhance.py`_"
    r = json.loads(path.read_text())
    m = r["machine"]
    names = {"four_walls_40px_per_m": "box, four synthetic facade photos, 40 px/m",
             "one_wall_8px_per_m": "box, one wall at 8 px/m (aerial-like)",
             "gable_wall_40px_per_m": "gable house (the street wall a pentagon)",
             "cmp_val_photos_street": "street of six CMP val photos, 50 px/m (dev photos)"}
    head = (f"Measured {r['date'][:10]} at commit `{r['commit']}` on {m['cores']} cores "
            f"({m['cpu']}), whole CLI processes.\n\n")
    rows = []
    for key, c in r["cases"].items():
        rows.append(f"| {names.get(key, key)} | {c['total_found']} / {c['total_truth']} | "
                    f"{100 * c['relative_error']:+.0f} % | {c['wall_seconds']:.1f} s |")
        b = c.get("through_batch")
        if b:
            same = "same windows" if b.get("same_windows_as_one_process") else "OTHER windows"
            rows.append(f"| the same through `enhance --batch` ({same}) | {b['total_found']} / "
                        f"{b['total_truth']} | {100 * b['relative_error']:+.0f} % | "
                        f"{b['wall_seconds']:.1f} s |")
    return (head + "| mass model | windows found / in the textures | error | wall time |\n"
            "|---|---|---|---|\n" + "\n".join(rows))


def replace(path: Path, marker: str, text: str) -> None:
    src = path.read_text()
    block = f"<!-- bench:{marker} -->\n{text}\n<!-- /bench:{marker} -->"
    pattern = re.compile(rf"<!-- bench:{marker} -->.*?<!-- /bench:{marker} -->", re.S)
    if pattern.search(src):
        src = pattern.sub(lambda _: block, src)
    else:
        src = src.replace(f"BENCH_TABLE:{marker}", block)
    path.write_text(src)


def main() -> None:
    table = engine_table()
    methods = methods_table()
    rec = reconstruct_table()
    parsing = parsing_table()
    summary = methods_table(SUMMARY_METHODS)
    repair = repair_table()
    prt = vs_prt_table()
    editor = editor_table()
    city = city_table()
    enhance = enhance_table()
    for p in (ROOT / "README.md", ROOT / "docs" / "benchmarks.md",
              ROOT / "benchmarks" / "README.md"):
        replace(p, "engine", table)
        replace(p, "methods", methods)
        replace(p, "summary", summary)
        replace(p, "reconstruct", rec)
        replace(p, "parsing", parsing)
        replace(p, "repair", repair)
        replace(p, "vs_prt", prt)
        replace(p, "editor", editor)
        replace(p, "city", city)
        replace(p, "enhance", enhance)
    print(table)
    print(methods)


if __name__ == "__main__":
    main()
