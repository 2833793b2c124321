"""facadeforge: facade photos and CGA rules → semantic, procedural, textured 3D buildings.

Thin: each command calls the public API.

Errors print one line (``facadeforge: error: …``) and exit with status 2; no tracebacks.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

from .errors import FacadeForgeError, InputError

#: ``facadeforge --help``'s epilog: one example per job; each command's own --help has more.
TOP_EXAMPLES = """examples:
  facadeforge demo -o demo-out                                  # the example building, a facade
  facadeforge derive examples/grammars/building.cga --lot 24x14 -o building.glb --stats
  facadeforge reconstruct photo.jpg -o out/                     # photo → procedural facade
  facadeforge parse photo.jpg -o parsed/                        # photo → parse grammar fit
  facadeforge points scan.ply -o scan-out/                      # laser scan → facades
  facadeforge multiview photos/ --cameras cameras_v2.txt -o mv/ # calibrated photos → 3D
  facadeforge repair photo.jpg -o clean/                        # trees and cars removed

  facadeforge COMMAND --help shows every option of a command, with examples."""


def _version() -> str:
    """The installed distribution's version (package metadata), else the source tree's."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("facadeforge")
    except PackageNotFoundError:  # run from a source tree that was never installed
        from . import __version__

        return __version__


EXAMPLES = {
    "derive": """examples:
  facadeforge derive examples/grammars/building.cga --lot 24x14 -o building.glb --stats
  facadeforge derive rules.cga --footprint lots.geojson --assets assets/ --attr height=30 -o city.city.json
  facadeforge derive package.rpk --rule rules/main.cga --footprint lots.geojson -o out.obj
  facadeforge derive src/facadeforge/gml/examples/fig13.gml -o fig13.glb --stats   # GML""",
    "batch": """examples:
  facadeforge batch examples/grammars/building.cga --footprint city.geojson -o city-out/
  facadeforge batch rules.cga --footprint north.geojson south.geojson -o city-out/ --chunk 100
  facadeforge batch rules.cga --footprint city.geojson -o city-out/ --scheduler tcp://head:8786
  (the same command again resumes a killed run: finished chunks are kept)""",
    "render": """examples:
  facadeforge render building.glb -o preview.png
  facadeforge render building.obj -o preview.png --size 1600x1200
  facadeforge render blocks.glb -o top.png --elevation 60 --azimuth 20""",
    "reconstruct": """examples:
  facadeforge reconstruct photo.jpg -o out/
  facadeforge reconstruct facade.png --rectified --width-m 18.5 -o out/
  facadeforge reconstruct photo.jpg --depths depths.json -o out/     # {"window": -0.3, "balcony": 1.2}
  facadeforge reconstruct facade.png --rectified --no-classifier -o out/   # the paper's edge-only path
  facadeforge reconstruct corner.jpg --facades one -o out/    # the whole photo as one facade""",
    "repair": """examples:
  facadeforge repair facade.png --rectified -o out/            # occluders found by the classifiers
  facadeforge repair facade.png --rectified --mask trees.png -o out/   # white = occluded
  facadeforge repair photo.jpg --labels labels.png --label-set cmp12 -o out/""",
    "synthesize": """examples:
  facadeforge synthesize drawn.png --label-set cmp12 --style photo.jpg -o texture.png
  facadeforge synthesize out/labels.png --label-set canonical --style facade.jpg \\
      --style-labels facade_labels.png -o texture.png""",
    "repair-model": """examples:
  facadeforge repair-model out/model.obj -o repaired/model.obj   # + model.mtl, textures/
  facadeforge repair-model city.glb -o city_repaired.glb --report repair.json
  facadeforge repair-model tiles.obj --up z -o fixed.glb          # a z-up OBJ""",
    "enhance": """examples:
  facadeforge enhance mass.glb -o enhanced/          # every textured facade made procedural
  facadeforge enhance city.obj --px-per-m 60 -o enhanced/   # aerial textures upsampled more
  facadeforge enhance city.obj --up z -o enhanced/          # a z-up model (GIS, photogrammetry)
  facadeforge enhance --batch city.glb -o city-enhanced/   # many buildings on a Dask cluster
  facadeforge enhance --batch north.obj south.obj -o city-enhanced/ --scheduler tcp://head:8786
  (--batch: resumable like `batch`; the same command again keeps the finished chunks)""",
    "multiview": """examples:
  facadeforge multiview photos/ --cameras cameras_v2.txt -o out/   # VisualSFM cameras
  facadeforge multiview photos/ --cameras sparse/0/ -o out/        # a COLMAP text model
  facadeforge multiview photos/ --cameras bundle.out -o out/       # Bundler (+ list.txt)
  facadeforge multiview photos/ --cameras cameras.txt --cloud dense.ply -o out/  # own cloud
  facadeforge multiview photos/ --cameras cameras.txt --scale 2.9 -o out/  # metres per unit""",
    "points": """examples:
  facadeforge points scan.ply -o out/                  # planes, depth maps, elements, model
  facadeforge points street.laz --resolution 0.1 -o out/
  facadeforge points scan.ply --photos photos/ --cameras cameras_v2.txt -o out/   # coloured
  facadeforge points facade.xyz --no-model -o out/     # planes, maps and elements only
  facadeforge points scan.ply --fit grammar -o out/    # + grid grammar fitted with depth energy""",
    "demo": """examples:
  facadeforge demo -o demo-out""",
    "edit": """examples:
  facadeforge edit out/                      # the OUTDIR of reconstruct or parse, in a browser
  facadeforge edit out/ --facade facade_01   # one facade of a street photo's OUTDIR
  facadeforge edit scan-out/ --facade facade_00   # a laser scan's facade (points OUTDIR)
  facadeforge edit out/ --port 8800 --no-browser   # then open the URL it prints""",
    "view": """examples:
  facadeforge view building.glb                      # any model we write
  facadeforge view out/model.glb scan.ply            # a points model over its scan
  facadeforge view city-out/tiles/tileset.json       # a 3D Tiles tileset""",
}


def _parse_attr(text: str) -> tuple[str, str]:
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"--attr '{text}' must be name=value")
    k, v = text.split("=", 1)
    return k.strip(), v.strip()


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = text.lower().split("x")
        return int(w), int(h)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size '{text}' must be WIDTHxHEIGHT, e.g. 1200x900") from None


def _angle(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not an angle in degrees, e.g. 30") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"'{text}' is not an angle in degrees, e.g. 30")
    return value


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"'{text}' must be a positive number")
    return value


def _elevation(text: str) -> float:
    value = _angle(text)
    if not -89.0 <= value <= 89.0:
        raise argparse.ArgumentTypeError(f"--elevation {value:g}° is out of range; give -89 to "
                                         "89 degrees above the horizon")
    return value


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser; with ``command``, the subcommands whose arguments live in
    heavy modules (dataset, training and benchmark code: 0.7 s of imports) are added only when
    they are that command, so that ``derive`` and ``render`` start fast."""
    def wanted(name: str) -> bool:
        return command in (None, name) or command not in COMMANDS

    p = argparse.ArgumentParser(prog="facadeforge", description=__doc__.splitlines()[0],
                                epilog=TOP_EXAMPLES,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"facadeforge {_version()}")
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("derive", help="derive CGA rules on footprints and export a 3D model",
                       epilog=EXAMPLES["derive"], formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument("rules", help=".cga file, CityEngine rule package (.rpk) or GML program "
                                 "(.gml: one that builds its own scope needs no --lot)")
    src = d.add_mutually_exclusive_group()
    src.add_argument("--footprint", help="GeoJSON (Polygon/FeatureCollection) or OBJ initial shapes")
    src.add_argument("--lot", help="a rectangular lot WIDTHxDEPTH in metres, e.g. 24x14")
    d.add_argument("--start", help="start rule (default: @StartRule, else the first rule)")
    d.add_argument("--style", help="CGA style of the rule file (default: Default)")
    d.add_argument("--rule", help="main rule file inside an .rpk")
    d.add_argument("--attr", action="append", type=_parse_attr, default=[], metavar="NAME=VALUE",
                   help="override an attribute (repeatable); imported ones as alias.name=value")
    d.add_argument("--assets", help="asset folder (relative asset paths resolve here)")
    d.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    d.add_argument("--strict", action="store_true", help="CGA warnings become errors")
    d.add_argument("--workers", type=int, default=None, help="processes (default: all cores)")
    d.add_argument("-o", "--output", required=True,
                   help="output file: .glb, .obj, .city.json, .city.jsonl (CityJSON Text Sequences, a "
                        "building a line), or .png/.svg (2D label layout)")
    d.add_argument("--stats", action="store_true", help="print statistics as one JSON object")
    d.add_argument("--max-seconds", type=_positive, default=None, metavar="S",
                   help="wall-clock seconds one building's derivation may take (default 30)")
    d.add_argument("--max-memory", type=_positive, default=None, metavar="MB",
                   help="memory a derivation may add, MiB, shared by the worker processes "
                        "(default 1536)")

    b = sub.add_parser("batch", help="derive CGA rules on a city's footprints on a Dask cluster: "
                       "resumable, CityJSONSeq chunks, 3D Tiles, buildings.csv",
                       epilog=EXAMPLES["batch"],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    b.add_argument("rules", help=".cga file or CityEngine rule package (.rpk); workers read it "
                                 "at this path")
    b.add_argument("--footprint", nargs="+", required=True, metavar="FILE",
                   help="GeoJSON or OBJ footprint files (one or more)")
    b.add_argument("-o", "--output", required=True,
                   help="output folder; the same command on it again resumes (docs/city.md)")
    b.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler, e.g. tcp://host:8786 (default: a local "
                        "cluster on 127.0.0.1)")
    b.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local cluster (default: all cores; not "
                        "with --scheduler)")
    b.add_argument("--chunk", type=int, default=50, metavar="N",
                   help="buildings a task and a 3D tile (default 50)")
    b.add_argument("--attr", action="append", type=_parse_attr, default=[], metavar="NAME=VALUE",
                   help="override an attribute (repeatable)")
    b.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    b.add_argument("--style", help="CGA style of the rule file (default: Default)")
    b.add_argument("--start", help="start rule (default: @StartRule, else the first rule)")
    b.add_argument("--rule", help="main rule file inside an .rpk")
    b.add_argument("--assets", help="asset folder (relative asset paths resolve here)")
    b.add_argument("--strict", action="store_true",
                   help="CGA warnings become errors (the building is recorded as failed)")
    b.add_argument("--max-seconds", type=_positive, default=None, metavar="S",
                   help="wall-clock seconds one building's derivation may take (default 30)")

    r = sub.add_parser("render", help="CPU preview render of a .glb or .obj model",
                       epilog=EXAMPLES["render"], formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("model")
    r.add_argument("-o", "--output", required=True, help="PNG file")
    r.add_argument("--size", type=_size, default=(1200, 900), help="WIDTHxHEIGHT (default 1200x900)")
    r.add_argument("--azimuth", type=_angle, default=-35.0,
                   help="camera direction round the vertical, degrees from the front (+z) towards "
                        "+x (default -35)")
    r.add_argument("--elevation", type=_elevation, default=25.0,
                   help="camera height, degrees above the horizon, -89 to 89 (default 25)")

    c = sub.add_parser("reconstruct", help="photo → shape tree, CGA rules and a textured 3D model",
                       epilog=EXAMPLES["reconstruct"],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("photo", help="facade photo (JPEG/PNG/TIFF…; gray, RGBA and 16-bit are fine)")
    c.add_argument("--rectified", action="store_true", help="the photo is already fronto-parallel")
    c.add_argument("--width-m", type=float, help="width of the facade in metres, without the "
                   "neighbours around it (else the floor-height prior)")
    c.add_argument("--height-m", type=float, help="facade height in metres")
    c.add_argument("--depths", help="JSON {label or cluster: depth in metres}, negative = recessed")
    c.add_argument("--seed", type=int, default=0, help="random seed of the rectification RANSAC")
    c.add_argument("--facades", choices=("auto", "one"), default="auto",
                   help="auto (default): find the facades of a street photo (the two sides of "
                        "a corner, houses side by side) and model each alone, in OUTDIR/"
                        "facade_01/, facade_02/… when there are several; one: the photo is "
                        "one facade")
    k = c.add_mutually_exclusive_group()
    k.add_argument("--classifier", help="pixel classifier .npz whose windows, doors and shops "
                   "structure the facade (default: the shipped cmp6 model with --rectified, "
                   "else ecp7, trained on Parisian street photos)")
    k.add_argument("--no-classifier", action="store_true",
                   help="elements from image edges only (Müller 2007 §2–3, no classifier)")
    c.add_argument("--no-repair", action="store_true",
                   help="texture the model with the photo as it is (default: trees, cars and "
                        "people in front of the facade are found and repaired first)")
    c.add_argument("-o", "--output", required=True, help="output folder")

    e = sub.add_parser("repair", help="remove trees, cars and people from a facade photo "
                       "(Shang 2023): repaired.png, mask.png, labels_completed.png, report.json",
                       epilog=EXAMPLES["repair"],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    e.add_argument("photo", help="facade photo")
    e.add_argument("--mask", help="what to repair: a PNG of the photo's size, non-zero = occluded "
                                  "(default: found by the classifiers)")
    e.add_argument("--labels", help="label PNG of the photo (its occluder pixels are the mask "
                                    "when there is no --mask; default: the facade classifier's)")
    e.add_argument("--label-set", default="canonical",
                   help="label set of --labels: canonical (default), cmp12, ecp7, lmf9 …")
    e.add_argument("--rectified", action="store_true",
                   help="the photo is already fronto-parallel (else it is rectified, repaired on "
                        "the facade and mapped back)")
    e.add_argument("--wall", choices=("quilt", "patchmatch"), default="quilt",
                   help="how wall is filled: image quilting from the visible wall (default, "
                        "§3.4) or label-guided PatchMatch")
    e.add_argument("--fill", choices=("expected", "texture"), default="expected",
                   help="expected (default): the hidden facade's expected colour (smooth "
                        "interpolation and the facade's periods) with some texture detail; "
                        "texture: the texture fill alone (repetition, quilting, PatchMatch), "
                        "sharper but less faithful")
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("-o", "--output", required=True, help="output folder")

    rm = sub.add_parser("repair-model", help="repair every facade texture of a textured 3D model "
                        "(Shang 2023 §4.2.2); the geometry is unchanged",
                        epilog=EXAMPLES["repair-model"],
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    rm.add_argument("model", help="textured model: .obj (with its .mtl and textures) or .glb")
    rm.add_argument("--up", choices=("y", "z"), default="y",
                    help="the model's up axis: y (default; facadeforge's models, glTF) or z")
    rm.add_argument("--report", help="also write the report (per texture and facade "
                                     "rectangle) as JSON to this file")
    rm.add_argument("--seed", type=int, default=0)
    rm.add_argument("-o", "--output", required=True,
                    help="output model, .obj (+ .mtl, textures/) or .glb")

    en = sub.add_parser("enhance", help="textured mass model → every textured facade "
                        "reconstructed and replaced by its procedural facade (Müller 2007 §1)",
                        epilog=EXAMPLES["enhance"],
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    en.add_argument("model", nargs="+", help="textured mass model: .obj (with its .mtl and "
                                             "textures) or .glb (metres); several with --batch")
    en.add_argument("--up", choices=("y", "z"), default="y",
                    help="the model's up axis: y (default; glTF, facadeforge's models) or z "
                         "(most city models)")
    en.add_argument("--px-per-m", type=_positive, default=40.0,
                    help="resolution of the unwrapped facade images, pixels per metre "
                         "(default 40; coarser textures are upsampled)")
    en.add_argument("--seed", type=int, default=0)
    en.add_argument("-o", "--output", required=True, help="output folder")
    en.add_argument("--batch", action="store_true",
                    help="enhance the buildings in chunks on a Dask cluster, as `batch` derives "
                         "a city: resumable, CityJSONSeq chunks, 3D Tiles, report.json "
                         "(docs/city.md)")
    en.add_argument("--scheduler", metavar="ADDRESS",
                    help="with --batch: a running Dask scheduler, e.g. tcp://host:8786 "
                         "(default: a local cluster on 127.0.0.1)")
    en.add_argument("--workers", type=int, default=None,
                    help="with --batch: worker processes of the local cluster (default: all "
                         "cores)")
    en.add_argument("--chunk", type=int, default=None, metavar="N",
                    help="with --batch: buildings a task and a 3D tile (default 8)")

    pt = sub.add_parser("points", help="laser scan → facade planes, depth maps, windows and "
                        "doors, CGA rules and a 3D model in the scan's coordinates (CityFit)",
                        epilog=EXAMPLES["points"],
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    pt.add_argument("cloud", help="point cloud: .ply, .las, .laz, .xyz, .txt, .csv or .pts "
                                  "(z up, metres)")
    pt.add_argument("--resolution", type=_positive, default=None,
                    help="cell size of the depth maps and orthophotos, metres (default: from "
                         "each facade's point spacing, 0.05 m or coarser)")
    pt.add_argument("--photos", help="folder of photos to colour the points from (with --cameras)")
    pt.add_argument("--cameras", help="cameras of the photos: VisualSFM cameras_v2.txt, Bundler "
                                      "bundle.out or a COLMAP text model")
    pt.add_argument("--fit", choices=("elements", "grammar"), default="elements",
                    help="elements (default): the facade's structure laid around the detected "
                         "windows and doors; grammar: also fit the grid parse grammar with "
                         "appearance and depth energies (Simon 2011 §5.3, SPEA-II) and keep it "
                         "where the automatic weight prefers it")
    pt.add_argument("--budget", type=int, default=600,
                    help="derivations of the grammar fit (--fit grammar; default 600)")
    pt.add_argument("--no-model", action="store_true",
                    help="find planes, maps and elements only; no rules or 3D model")
    pt.add_argument("--seed", type=int, default=0)
    pt.add_argument("-o", "--output", required=True, help="output folder")

    mv = sub.add_parser("multiview", help="calibrated photos of a building → its facades fitted "
                        "in 3D with appearance and depth energies (Simon 2011 ch. 5)",
                        epilog=EXAMPLES["multiview"],
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    mv.add_argument("photos", help="folder of the photos (named by the cameras' ids or files)")
    mv.add_argument("--cameras", required=True,
                    help="their calibrated cameras: VisualSFM cameras_v2.txt, Bundler bundle.out "
                         "or a COLMAP text model (folder or images.txt)")
    mv.add_argument("--cloud", help="a point cloud in the cameras' frame to use instead of the "
                                    "stereo (PLY, LAS/LAZ, XYZ)")
    mv.add_argument("--scale", type=_positive, default=None,
                    help="metres per camera unit (default: from the cameras' eye height above "
                         "the ground)")
    mv.add_argument("--budget", type=int, default=1500,
                    help="derivations of the grammar search per facade (default 1500)")
    mv.add_argument("--no-depth-energy", action="store_true",
                    help="fit with the appearance energy alone (no E_d against the cloud)")
    mv.add_argument("--seed", type=int, default=0)
    mv.add_argument("-o", "--output", required=True, help="output folder")

    y = sub.add_parser("synthesize", help="a facade texture from a label map in the style of a "
                       "photo (Shang 2023 §3.3: the missing-texture case)",
                       epilog=EXAMPLES["synthesize"],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    y.add_argument("labels", help="label PNG: what to paint where")
    y.add_argument("--label-set", default="cmp12",
                   help="label set of the label PNGs: cmp12 (default), cmp6, ecp7, lmf9 or "
                        "canonical (the labels.png facadeforge writes)")
    y.add_argument("--style", required=True, help="photo whose style (one per class) is used")
    y.add_argument("--style-labels", help="label PNG of the style photo (default: labelled by "
                                          "the shipped cmp12 classifier)")
    y.add_argument("--no-color-match", action="store_true",
                   help="keep the network's colours (default: each class's mean colour is "
                        "matched to the style photo's)")
    y.add_argument("-o", "--output", required=True, help="output PNG")

    if wanted("parse"):
        from .parsing import DEFAULT_BUDGET

        g = sub.add_parser("parse", help="photo → best derivation of a parse grammar (Simon 2011)",
                           description="Fit a parse grammar to a facade photo: pixel classifier "
                                       "→ energy → hill climbing or evolutionary search → shape "
                                       "tree, labels, fitted rules and 3D model in OUTDIR.",
                           epilog="examples:\n"
                                  "  facadeforge parse street.jpg -o parsed/\n"
                                  "  facadeforge parse facade.png --rectified --grammar generic "
                                  "--method hill --budget 3000 -o parsed/",
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        g.add_argument("photo", help="facade photo")
        g.add_argument("--grammar", help="parse grammar: grid (default), haussmann, generic or a "
                                         ".cga file")
        g.add_argument("--classifier", help="classifier model .npz (default: the shipped model)")
        g.add_argument("--method", default="evolution", choices=("hill", "evolution"),
                       help="search: evolution (default, §5.2) or hill (Alg. 4.1)")
        g.add_argument("--budget", type=int, default=DEFAULT_BUDGET,
                       help=f"derivations (default {DEFAULT_BUDGET})")
        g.add_argument("--rectified", action="store_true", help="the photo is already rectified")
        g.add_argument("--width-m", type=float, help="facade width in metres (scales the model)")
        g.add_argument("--seed", type=int, default=0)
        g.add_argument("-o", "--output", required=True, help="output folder")
    if wanted("synth"):
        from .datasets.synthetic import add_parser as add_synth

        add_synth(sub)
    if wanted("bench"):
        from .evaluation.bench import add_parser as add_bench

        add_bench(sub)
    if wanted("train-classifier"):
        from .classify.train import add_parser as add_train

        add_train(sub)

    ed = sub.add_parser("edit", help="correct a reconstruction in the browser: drag split lines, "
                        "set depths, change elements; the 3D model follows; save rewrites OUTDIR",
                        epilog=EXAMPLES["edit"], formatter_class=argparse.RawDescriptionHelpFormatter)
    ed.add_argument("outdir", help="OUTDIR of `facadeforge reconstruct`, `parse` or `points`")
    ed.add_argument("--facade", default=None, metavar="NAME",
                    help="which facade folder of a street photo's or a scan's OUTDIR "
                         "(facade_01); default the first")
    ed.add_argument("--port", type=int, default=0,
                    help="port on 127.0.0.1 (default: any free one)")
    ed.add_argument("--no-browser", action="store_true",
                    help="print the URL only; do not open a browser")
    vw = sub.add_parser("view", help="look at models (.glb .obj .city.json .city.jsonl, a 3D "
                        "Tiles tileset.json) and point clouds (.ply .las …) in the browser",
                        epilog=EXAMPLES["view"], formatter_class=argparse.RawDescriptionHelpFormatter)
    vw.add_argument("files", nargs="+", metavar="FILE", help="models and point clouds, drawn "
                    "together")
    vw.add_argument("--port", type=int, default=0,
                    help="port on 127.0.0.1 (default: any free one)")
    vw.add_argument("--no-browser", action="store_true",
                    help="print the URL only; do not open a browser")

    m = sub.add_parser("demo", help="derive the example building and reconstruct a synthetic facade",
                       epilog=EXAMPLES["demo"], formatter_class=argparse.RawDescriptionHelpFormatter)
    m.add_argument("-o", "--output", default="demo-out", help="output folder (default demo-out)")
    return p


def suffix_of(path: str) -> str:
    name = Path(path).name.lower()
    return "city.json" if name.endswith(".city.json") else Path(name).suffix.lstrip(".")


def cmd_derive(args) -> int:
    from . import engine, export
    from .geometry.footprints import load_footprints
    from .outdir import check_output_file

    check_output_file(args.output, {"--footprint": args.footprint, "rules": args.rules})
    if str(args.rules).lower().endswith(".gml"):
        unused = [f for f, v in (("--attr", args.attr), ("--start", args.start),
                                 ("--style", args.style), ("--rule", args.rule)) if v]
        if unused:
            raise InputError(f"{', '.join(unused)} apply to CGA rules, not to the GML program "
                             f"{args.rules}")
    elif not args.footprint and not args.lot:
        raise InputError("give footprints (--footprint FILE) or a lot size (--lot WxD)")
    t0 = time.perf_counter()
    footprints = load_footprints(args.footprint) if args.footprint else None
    if footprints and footprints[0].attributes.get("_projected"):
        print(f"footprints projected: {footprints[0].attributes['_projected']}", file=sys.stderr)
    total = len(footprints) if footprints is not None else 1
    progress = sys.stderr.isatty() and total > 1  # a city takes a while: say how far it got
    from .grammar.interpreter import Limits

    limits = Limits()
    if args.max_seconds is not None:
        limits.max_seconds = args.max_seconds
    if args.max_memory is not None:
        limits.max_memory_mb = args.max_memory
    derived = engine.derive_iter(args.rules, footprints, lot_size=args.lot, limits=limits,
                                 start=args.start, style=args.style, attrs=dict(args.attr),
                                 assets=args.assets, seed=args.seed, strict=args.strict,
                                 rule=args.rule, workers=args.workers,
                                 keep_tree=suffix_of(args.output) in ("png", "svg"))
    models = []  # what --stats needs of each building; the geometry goes on to the file

    def tap(items):
        for m in items:
            for line in m.attributes.get("prints", []):  # stderr: --stats keeps stdout JSON
                print(f"print: {line}", file=sys.stderr)
            models.append(engine.summary(m))
            if progress:
                print(f"\r{len(models)}/{total} buildings", end="", file=sys.stderr, flush=True)
            yield m
    export(tap(derived), args.output)
    if progress:
        print("\r" + " " * 30 + "\r", end="", file=sys.stderr, flush=True)
    seconds = time.perf_counter() - t0
    if args.stats:
        print(json.dumps(engine.stats(models, seconds), allow_nan=False))
    else:
        s = engine.stats(models, seconds)
        print(f"{len(models)} building(s), {s['faces']} faces, {s['triangles']} triangles, "
              f"{len(s['warnings'])} warning(s) → {args.output} ({seconds:.2f} s)")
        for w in s["warnings"][:10]:
            print(f"warning: {w}", file=sys.stderr)
    return 0


def cmd_batch(args) -> int:
    from .city import batch
    from .grammar.interpreter import Limits

    limits = Limits()
    if args.max_seconds is not None:
        limits.max_seconds = args.max_seconds
    r = batch(args.rules, args.footprint, args.output, scheduler=args.scheduler,
              workers=args.workers, chunk=args.chunk, attrs=dict(args.attr), seed=args.seed,
              style=args.style, assets=args.assets, start=args.start, rule=args.rule,
              strict=args.strict, limits=limits)
    print(f"{r.buildings} building(s) in {r.chunks} chunk(s) ({r.derived} derived, {r.skipped} "
          f"kept from an earlier run), {len(r.failed)} failed → {args.output}/ "
          f"({r.seconds:.1f} s)")
    _chunk_problems(r)
    return 0


def _chunk_problems(r) -> None:
    """The first failed buildings and notes of a batch run, on stderr."""
    for chunk, name, message in r.failed[:10]:
        print(f"failed: chunk {chunk}: {name}: {message}", file=sys.stderr)
    for chunk, message in r.notes[:10]:
        print(f"note: chunk {chunk}: {message}", file=sys.stderr)


def _announce(url: str) -> None:
    print(url, flush=True)     # the first line: the URL with the session's token
    print("serving on 127.0.0.1 only; Ctrl-C stops", file=sys.stderr, flush=True)


def cmd_edit(args) -> int:
    from .editor.server import editor_app, serve
    from .editor.session import EditSession

    session = EditSession(args.outdir, facade=args.facade)
    serve(lambda token: editor_app(session, token), args.port,
          open_browser=not args.no_browser, announce=_announce)
    if session.version != session.saved_version:
        print(f"facadeforge edit: {len(session.log)} edit(s) not saved", file=sys.stderr)
    return 0


def cmd_view(args) -> int:
    from .editor.scene import load_scene
    from .editor.server import serve, viewer_app

    scene = load_scene(args.files)
    serve(lambda token: viewer_app(scene, token), args.port,
          open_browser=not args.no_browser, announce=_announce)
    return 0


def cmd_render(args) -> int:
    from . import render

    render(args.model, args.output, size=args.size, azimuth=args.azimuth,
           elevation=args.elevation)
    print(f"rendered {args.model} → {args.output}")
    return 0


def _plural(word: str, n: int) -> str:
    """``word`` for ``n`` things (``balcony`` → ``balconies``)."""
    if n == 1:
        return word
    return word[:-1] + "ies" if word.endswith("y") and word[-2:-1] not in "aeiou" else word + "s"


def _summary(rec, out) -> str:
    r = rec.report
    f = r["facade"]
    els = ", ".join(f"{n} {_plural(k, n)}" for k, n in sorted(r["elements"].items())
                    ) or "no elements"
    d = r["detection"]
    src = (f"the {d['classifier']['label_set']} {d['classifier']['kind']} classifier"
           if d["source"] == "classifier" else "image edges")
    t = r["timings"]
    lines = [f"facade {f['width_m']:.1f} m × {f['height_m']:.1f} m (scale: {f['scale_source']}): "
             f"{r['floors']} floors, {r['tiles']} tiles in {r['tile_clusters']} clusters, {els} "
             f"(elements from {src})",
             "timings: " + ", ".join(f"{k} {v:.2f} s" for k, v in t.items()),
             ("needs review: " + "; ".join(r["flags"])) if r["needs_review"] else "no review flags",
             _repair_line(r.get("repair")),
             *(f"note: {n}" for n in r.get("notes", [])),
             f"wrote {out}/: rectified.png structure.png labels.png labels_input.png "
             "shape_tree.json rules.cga rules.gml model.glb model.obj model.city.json report.json"]
    return "\n".join(lines)


def _repair_line(rep) -> str:
    """What the texture repair did, one line."""
    if rep is None:
        return "texture: the photo as it is (--no-repair)"
    if not rep["mask"]["pixels"]:
        return "texture: no occluder found in front of the facade"
    filled = ", ".join(f"{k} {v} px" for k, v in rep["filled"].items() if v)
    return (f"texture repaired: {100 * rep['mask']['fraction']:.1f} % of the facade occluded "
            f"(mask from {rep['mask']['source']}), filled by {filled}")


def _facades_summary(result, out) -> str:
    """What ``reconstruct`` prints for a photo of several facades."""
    r = result.report
    lines = [f"{len(r['facades'])} facades found, {len(result.facades)} modelled "
             f"(find_facades {r['timings']['facades']:.2f} s)"]
    for e in r["facades"]:
        if e["folder"] is None:
            lines.append(f"facade {e['id']}: not modelled: {'; '.join(e['flags'])}")
    for rec, folder in zip(result.facades, result.folders()):
        lines.append(f"{folder}: " + _summary(rec, f"{out}/{folder}"))
    lines += [f"note: {n}" for n in r.get("notes", [])]
    lines.append(f"wrote {out}/: {' '.join(f + '/' for f in result.folders())} facades.png "
                 "labels_input.png report.json")
    return "\n".join(lines)


def cmd_reconstruct(args) -> int:
    from .reconstruction import reconstruct_facades

    result = reconstruct_facades(args.photo, facades=args.facades, rectified=args.rectified,
                                 width_m=args.width_m, height_m=args.height_m,
                                 depths=args.depths, out_dir=args.output,
                                 classifier=False if args.no_classifier else args.classifier,
                                 repair=not args.no_repair, seed=args.seed)
    if result.single is not None:
        print(_summary(result.single, args.output))
    else:
        print(_facades_summary(result, args.output))
    return 0


def cmd_demo(args) -> int:
    from . import engine, export, render
    from .outdir import check_outdir, write_outdir

    out = Path(args.output)
    check_outdir(out)          # before the work: OUTDIR is replaced whole (outdir.py)
    grammar = Path(__file__).resolve().parent / "data" / "building.cga"
    lines: list[str] = []      # printed once the folder is in place

    def write(stage: Path) -> None:
        t0 = time.perf_counter()
        models = engine.derive(grammar, lot_size="24x14")
        seconds = time.perf_counter() - t0
        files = []
        for suffix in ("glb", "obj", "city.json"):
            export(models, stage / f"building.{suffix}")
            files.append(str(out / f"building.{suffix}"))
        render(models, stage / "preview.png")
        files.append(str(out / "preview.png"))
        s = engine.stats(models, seconds)
        lines.append(f"derived {grammar.name} on a 24 m × 14 m lot in {seconds:.2f} s: "
                     f"{s['shapes']} shapes, {s['faces']} faces, {s['triangles']} triangles")
        for k, v in sorted(s["report"].items()):
            lines.append(f"  report {k}: n={len(v)} "
                         f"sum={sum(x for x in v if isinstance(x, float)):.2f}")
        lines.append("wrote " + ", ".join(files))
        lines.append(_demo_reconstruct(stage, out))

    write_outdir(out, write)
    print("\n".join(lines))
    return 0


def _demo_reconstruct(stage: Path, out: Path) -> str:
    """A synthetic Haussmann facade (exact truth) → reconstruct → summary with window F1;
    written into ``stage``, described as in ``out``."""
    from . import render
    from .datasets.synthetic import generate
    from .evaluation.metrics import match_boxes
    from .jsonfile import read_json
    from .reconstruction import reconstruct

    photo = generate(1, seed=11, out_dir=stage / "synthetic", size=640, styles=["haussmann"])[0]
    # the files were written just now, but through the one reader of JSON files all the same:
    # a full disk or a tampered folder is a message naming the file, not a traceback
    fix = "run facadeforge demo again"
    meta = read_json(photo.with_suffix(".meta.json"), "synthetic metadata", fix=fix)
    objects = read_json(photo.with_suffix(".objects.json"), "synthetic objects", fix=fix)
    rec = reconstruct(photo, rectified=True, width_m=meta["facade_size_m"][0])
    rec.report["input"]["photo"] = str(out / "synthetic" / photo.name)   # not the stage's
    rec.save(stage / "reconstruction")
    truth = [o["box"] for o in objects if o["label"] == "window"]
    score = match_boxes(truth, rec.windows(frame="input"))
    if rec.model is not None:
        render(rec.model, stage / "reconstruction" / "preview.png")
    return (f"\nreconstructed the synthetic facade {photo.name} (truth: {len(truth)} windows):\n"
            f"{_summary(rec, out / 'reconstruction')}\n"
            f"windows: precision {score.precision:.2f}, recall {score.recall:.2f}, "
            f"F1 {score.f1:.2f} (IoU ≥ 0.5)")


def cmd_bench(args) -> int:
    from .evaluation.bench import cmd_bench as run

    return run(args)


def cmd_synth(args) -> int:
    from .datasets.synthetic import cmd_synth as run

    return run(args)


def cmd_parse(args) -> int:
    from .outdir import check_outdir
    from .parsing.parse import parse

    check_outdir(args.output, {"photo": args.photo, "--grammar": args.grammar,
                               "--classifier": args.classifier})   # before the search
    result = parse(args.photo, grammar=args.grammar, classifier=args.classifier,
                   method=args.method, budget=args.budget, rectified=args.rectified,
                   width_m=args.width_m, seed=args.seed)
    result.save(args.output)
    r = result.report
    e = r["elements"]
    print(f"parsed {args.photo} with {Path(r['grammar']).stem} ({r['method']}, "
          f"{r['derivations']} derivations, energy {r['energy_per_pixel']:.3f}/px): "
          f"{e['window']} windows, {e['door']} doors, {e['balcony']} balconies, {e['shop']} "
          f"shops; {r['timings']['total']:.2f} s → {args.output}")
    return 0


def _read_labels(path: str, label_set: str):
    """A label PNG as canonical label indices (``label_set`` says how to read it; canonical:
    the index or palette PNG ``reconstruct`` and ``repair`` write, or its colours)."""
    import numpy as np

    from .datasets.folder import read_label_image
    from .errors import InputError

    raw = read_label_image(path, palette_as_color=False)
    if label_set == "canonical":
        from .exchange.raster import PALETTE

        if raw.ndim == 2:
            return np.asarray(raw, np.int64)
        key = (raw[..., 0].astype(np.int64) << 16) | (raw[..., 1].astype(np.int64) << 8) | raw[..., 2]
        pal = (PALETTE[:, 0].astype(np.int64) << 16) | (PALETTE[:, 1].astype(np.int64) << 8) | PALETTE[:, 2]
        order = np.argsort(pal)
        pos = np.clip(np.searchsorted(pal[order], key), 0, len(pal) - 1)
        if not (pal[order][pos] == key).all():
            raise InputError(f"--labels {path}: colours that are not canonical label colours; "
                             "give --label-set (cmp12, ecp7, lmf9 …) for a dataset's label PNG")
        return order[pos].astype(np.int64)
    from .datasets.labelsets import CANONICAL_INDEX, IGNORE, get_label_set

    ls = get_label_set(label_set)
    if raw.ndim == 3:
        idx = ls.from_color(raw, strict=True)
    else:
        idx = ls.from_dataset(raw, strict=True)
    canon = ls.to_canonical(idx).astype(np.int64)
    canon[canon == IGNORE] = CANONICAL_INDEX["other"]   # unlabelled: a piece of the scene
    return canon


def cmd_repair(args) -> int:
    from .repair.pipeline import repair_photo

    labels = _read_labels(args.labels, args.label_set) if args.labels else None
    r = repair_photo(args.photo, mask=args.mask, labels=labels, rectified=args.rectified,
                     wall=args.wall, fill=args.fill, seed=args.seed, out_dir=args.output)
    rep = r.report
    filled = ", ".join(f"{k} {v} px" for k, v in rep["filled"].items() if v) or "nothing"
    print(f"repaired {args.photo}: mask from {rep['mask']['source']} "
          f"({100 * rep['mask']['fraction']:.1f} % of the photo); filled by {filled}; "
          f"{rep['timings']['total']:.2f} s → {args.output}/repaired.png mask.png "
          "labels_completed.png report.json")
    return 0


def _cmp12_labels(path: str, label_set: str):
    """A label PNG as ``cmp12`` class indices (what the synthesis network paints)."""
    from .datasets.labelsets import get_label_set

    cmp12 = get_label_set("cmp12")
    if label_set == "cmp12":
        from .datasets.folder import read_label_image

        raw = read_label_image(path)
        return cmp12.from_color(raw, strict=True) if raw.ndim == 3 else cmp12.from_dataset(
            raw, strict=True)
    return cmp12.from_canonical(_read_labels(path, label_set))


def cmd_synthesize(args) -> int:
    from PIL import Image

    from .datasets.folder import read_image
    from .outdir import check_output_file
    from .repair.synthesis import synthesize

    if not args.output.lower().endswith(".png"):
        from .errors import InputError

        raise InputError(f"-o {args.output}: the texture is written as PNG; use e.g. -o out.png")
    check_output_file(args.output, {"labels": args.labels, "--style": args.style})
    t = time.perf_counter()
    labels = _cmp12_labels(args.labels, args.label_set)
    style = read_image(args.style)
    style_labels = (_cmp12_labels(args.style_labels, args.label_set) if args.style_labels
                    else None)
    out = synthesize(labels, style, style_labels, label_set="cmp12",
                     match_colors=not args.no_color_match)
    import io

    from .exchange._common import Staging

    buf = io.BytesIO()
    Image.fromarray(out).save(buf, format="PNG")
    with Staging() as stage:        # written whole or not at all
        stage.write_bytes(args.output, buf.getvalue())
    print(f"synthesized {out.shape[1]}x{out.shape[0]} px texture in the style of {args.style} "
          f"({time.perf_counter() - t:.2f} s) → {args.output}")
    return 0


def cmd_repair_model(args) -> int:
    from .repair.model_textures import repair_model

    rep = repair_model(args.model, args.output, seed=args.seed, up=args.up,
                       report_path=args.report)
    s = rep["summary"]
    share = 100 * s["pixels"] / max(s["rectangle_pixels"], 1)
    extra = f" and {args.report}" if args.report else ""
    print(f"repaired {args.model}: {s['textures_repaired']} of {s['textures']} textures, "
          f"{s['rectangles_repaired']} of {s['facade_rectangles']} facade rectangles, "
          f"{s['pixels']} px ({share:.1f} % of the facades); {s['seconds']['total']:.2f} s "
          f"→ {args.output}{extra}")
    return 0


def cmd_enhance(args) -> int:
    from .city.enhance import enhance

    given = [f for f, v in (("--scheduler", args.scheduler), ("--workers", args.workers),
                            ("--chunk", args.chunk)) if v is not None]
    if not args.batch and (given or len(args.model) > 1):
        why = f"{given[0]} is" if given else "several models are"
        raise InputError(f"{why} for a batch of buildings: add --batch (outputs per chunk and a "
                         "3D tileset, docs/city.md), or give one model without it")
    if args.batch:
        return _enhance_batch(args)
    r = enhance(args.model[0], args.output, px_per_m=args.px_per_m, seed=args.seed,
                up=args.up)
    s = r.report["summary"]
    print(f"{args.model[0]}: {s['facades']} {_plural('facade', s['facades'])} reconstructed "
          f"({s['windows']} {_plural('window', s['windows'])}), {s['skipped']} "
          f"{_plural('wall', s['skipped'])} skipped, {s['kept_faces']} faces kept; "
          f"{s['seconds']['total']:.1f} s → {args.output}")
    return 0


def _enhance_batch(args) -> int:
    import json

    from .city.enhance_batch import DEFAULT_CHUNK, enhance_batch

    r = enhance_batch(args.model, args.output, px_per_m=args.px_per_m, seed=args.seed,
                      up=args.up, scheduler=args.scheduler, workers=args.workers,
                      chunk=args.chunk if args.chunk is not None else DEFAULT_CHUNK)
    s = json.loads((r.outdir / "report.json").read_text(encoding="utf-8"))["summary"]
    print(f"{r.buildings} building(s) in {r.chunks} chunk(s) ({r.derived} enhanced, {r.skipped} "
          f"kept from an earlier run): {s['facades']} {_plural('facade', s['facades'])} "
          f"reconstructed ({s['windows']} {_plural('window', s['windows'])}), {s['skipped']} "
          f"{_plural('wall', s['skipped'])} skipped, {len(r.failed)} failed → {args.output}/ "
          f"({r.seconds:.1f} s)")
    _chunk_problems(r)
    return 0


def cmd_points(args) -> int:
    from .points.pipeline import points

    r = points(args.cloud, resolution=args.resolution, photos=args.photos, cameras=args.cameras,
               model=not args.no_model, fit=args.fit, budget=args.budget, seed=args.seed,
               out_dir=args.output)
    kinds = Counter(p["kind"] for p in r.report["planes"])
    els = Counter(e["label"] for e in r.elements())
    found = ", ".join(f"{n} {_plural(k, n)}" for k, n in sorted(els.items())) or "no elements"
    print(f"{args.cloud}: {len(r.cloud):,} points, {len(r.planes)} planes "
          f"({kinds.get('facade', 0)} {_plural('facade', kinds.get('facade', 0))}, "
          f"{kinds.get('ground', 0)} ground), {found}; "
          f"{r.report['timings']['total']:.1f} s → {args.output}")
    for note in r.report.get("notes", []):
        print(f"note: {note}", file=sys.stderr)
    return 0


def cmd_multiview(args) -> int:
    from .multiview.pipeline import multiview

    r = multiview(args.photos, args.cameras, cloud=args.cloud, metres_per_unit=args.scale, budget=args.budget, seed=args.seed,
                  depth_energy=not args.no_depth_energy, out_dir=args.output)
    n = sum(1 for f in r.facades if f.model is not None)
    els = Counter()
    for f in r.facades:
        els.update(f.report.get("elements", {}))
    found = ", ".join(f"{v} {_plural(k, v)}" for k, v in sorted(els.items()) if v) or "no elements"
    print(f"{args.photos}: {len(r.views)} photos, {len(r.cloud):,} points, {n} "
          f"{_plural('facade', n)} modelled ({found}); {r.report['timings']['total']:.1f} s → "
          f"{args.output}")
    for note in r.report.get("notes", []):
        print(f"note: {note}", file=sys.stderr)
    return 0


def cmd_train_classifier(args) -> int:
    from .classify.train import cmd_train_classifier as run

    return run(args)


COMMANDS = {"derive": cmd_derive, "batch": cmd_batch, "render": cmd_render, "demo": cmd_demo, "bench": cmd_bench,
            "synth": cmd_synth, "reconstruct": cmd_reconstruct,
            "train-classifier": cmd_train_classifier, "parse": cmd_parse, "repair": cmd_repair,
            "synthesize": cmd_synthesize, "repair-model": cmd_repair_model,
            "points": cmd_points, "edit": cmd_edit, "view": cmd_view, "enhance": cmd_enhance,
            "multiview": cmd_multiview}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv[0] if argv else None)
    args = parser.parse_args(argv)
    from .scratch import Terminated, sigterm_as_exit

    try:
        # Python warnings of the libraries (numpy's overflow on absurd sizes, pygltflib on an
        # unknown chunk) are not the user's business: what matters reaches them as a CGA
        # warning or as the one error line
        with sigterm_as_exit(), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return COMMANDS[args.command](args)
    except FacadeForgeError as e:
        first = str(e).splitlines()[0]
        print(f"facadeforge: error: {first}", file=sys.stderr)
        return 2
    except (OSError, ValueError) as e:
        print(f"facadeforge: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("facadeforge: interrupted", file=sys.stderr)
        return 130
    except Terminated as e:
        print("facadeforge: terminated", file=sys.stderr)
        return e.code
    except Exception as e:  # a bug: still one line, with what to report
        print(f"facadeforge: internal error: {type(e).__name__}: {e} (please report this with "
              "the command and its input files)", file=sys.stderr)
        return 3


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
