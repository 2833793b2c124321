"""CityEngine rule packages (``.rpk``): 7z archives of rules, assets and a ``.resolvemap.xml``.

An open runtime can only run CGA *source*: packages exported with "include CGA source" carry the
``.cga`` next to the compiled ``.cgb``; packages with ``.cgb`` only are refused with that hint.

A package is unpacked into a temporary folder named after the process
(``facadeforge-rpk-<host>-<pid>-*``, :mod:`facadeforge.scratch`): it is removed when the
package object goes, when the unpacking fails or is stopped by SIGTERM (turned into a normal
exit for the time of the unpacking), and, when the process was killed outright, by the next
``open_rpk``.
"""

from __future__ import annotations

import shutil
import threading
import weakref
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from ..errors import InputError
from ..scratch import scratch_dir, sigterm_as_exit

#: Largest total a package may unpack to (bytes).  Checked twice: before anything is written,
#: from the sizes the archive's listing declares, and while it is written, from the bytes really
#: decompressed (py7zr's ``max_extract_size``), so a listing that lies stops at the cap too.  A
#: package holds rules and the assets they insert: the Candler example is 1.1 MB packed, 1.2 MB
#: unpacked; packages with a texture library run to a few hundred megabytes.  A 7z of zeros
#: packs 1 GiB into about 150 KiB, which this refuses before it costs the disk anything.
MAX_UNPACKED_BYTES = 1024**3
#: Most members (files and folders) a package may list: Candler has 28; a large asset library
#: has thousands.  Each member is a file to create and a name to check.
MAX_MEMBERS = 100_000
#: Largest package file opened: beyond it even the packed bytes exceed what it may unpack to.
MAX_PACKAGE_BYTES = MAX_UNPACKED_BYTES


@dataclass
class RulePackage:
    root: Path  # unpacked folder (a temporary directory owned by this object)
    main: Path  # main .cga file
    resolve_map: dict  # project-absolute path -> file in root

    def cleanup(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)


def open_rpk(path: str | Path, rule: str | None = None) -> RulePackage:
    """Unpack a rule package safely and find its main rule file.

    Parameters
    ----------
    path : path to the ``.rpk``
    rule : str, optional
        Main rule file inside the package (``rules/building.cga``); default as CityEngine: the
        rule file that has a compiled ``.cgb`` twin (beside it, or in the package's ``bin/``),
        else the only ``.cga`` in ``rules/``, else the first with ``@StartRule``.
    """
    import py7zr
    from py7zr.exceptions import DecompressionBombError

    p = Path(path)
    if not p.is_file():
        raise InputError(f"rule package '{path}' does not exist")
    if p.stat().st_size > MAX_PACKAGE_BYTES:
        raise InputError(f"rule package '{path}' is {p.stat().st_size >> 20} MiB, more than "
                         f"the {MAX_PACKAGE_BYTES >> 20} MiB facadeforge unpacks; split it")
    root = scratch_dir("facadeforge-rpk-")   # also removes those of killed runs
    cap = MAX_UNPACKED_BYTES
    try:
        try:
            with sigterm_as_exit(), py7zr.SevenZipFile(p, "r", max_extract_size=cap) as z:
                infos = z.list()
                if len(infos) > MAX_MEMBERS:
                    raise InputError(f"rule package '{path}' has {len(infos)} members, more "
                                     f"than the {MAX_MEMBERS} facadeforge unpacks")
                total = 0
                for info in infos:
                    name = PurePosixPath(info.filename.replace("\\", "/"))
                    if name.is_absolute() or ".." in name.parts:
                        raise InputError(f"'{path}' contains an unsafe member path '{info.filename}'")
                    total += max(int(info.uncompressed or 0), 0)
                if total > cap:  # a decompression bomb: refused before a byte is written
                    raise InputError(f"rule package '{path}' unpacks to {_mib(total)}, more "
                                     f"than the {_mib(cap)} facadeforge unpacks")
                free = shutil.disk_usage(root).free
                if total > free:
                    raise InputError(f"rule package '{path}' unpacks to {_mib(total)}, but the "
                                     f"temporary folder {root.parent} has {_mib(free)} free; "
                                     "free some space or set TMPDIR")
                z.extractall(path=root)
        except InputError:
            raise
        except DecompressionBombError:  # the listing understated the sizes
            raise InputError(f"rule package '{path}' unpacks to more than the {_mib(cap)} "
                             "facadeforge unpacks (more than its listing says: a damaged or "
                             "forged package)") from None
        except Exception as e:  # py7zr raises many types for corrupt archives
            raise InputError(f"'{path}' is not a readable rule package (7z): {e}") from None
        resolve_map = _read_resolvemap(root)
        main = _find_main(root, rule, path)
        package = RulePackage(root, main, resolve_map)
        # the unpacked folder lives as long as the package object (rules, assets refer to it)
        weakref.finalize(package, shutil.rmtree, root, True)
        return package
    except BaseException:
        shutil.rmtree(root, ignore_errors=True)
        # py7zr unpacks the folders of a non-solid archive in threads of its own, which a
        # signal does not stop: once they end, remove what they wrote after the removal above
        workers = [t for t in threading.enumerate() if "(extract_single)" in t.name]
        for t in workers:
            t.join(timeout=120)
        if workers:
            shutil.rmtree(root, ignore_errors=True)
        raise


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


def _read_resolvemap(root: Path) -> dict:
    out = {}
    for xml in root.rglob("*.resolvemap.xml"):
        try:
            tree = ET.parse(xml)
        except ET.ParseError:
            continue
        for el in tree.iter():
            key, value = el.attrib.get("key"), el.attrib.get("value")
            if not key or not value:
                continue
            target = (root / value.lstrip("/")).resolve()
            if root.resolve() in target.parents and target.is_file():
                out[key] = target
    return out


def _find_main(root: Path, rule: str | None, path) -> Path:
    cgas = sorted(root.rglob("*.cga"))
    if rule:
        cand = (root / rule.lstrip("/")).resolve()
        if root.resolve() not in cand.parents or not cand.is_file():
            names = ", ".join(str(c.relative_to(root)) for c in cgas) or "none"
            raise InputError(f"--rule '{rule}' is not in '{path}' (rule files: {names})")
        return cand
    if not cgas:
        cgbs = sorted(root.rglob("*.cgb"))
        if cgbs:
            raise InputError(f"'{path}' holds only compiled rules ({cgbs[0].name}); export it from "
                             "CityEngine with 'Include CGA source', or pass the .cga file")
        raise InputError(f"'{path}' holds no rule file")
    top = [c for c in cgas if c.parent.name == "rules"] or cgas
    with_cgb = [c for c in top if c.with_suffix(".cgb").is_file()]
    if len(with_cgb) == 1:
        return with_cgb[0]
    # CityEngine puts the compiled main rule in bin/ (bin/x.cgb beside rules/x.cga): the rule
    # file whose compiled twin is anywhere in the package
    compiled = {c.stem for c in root.rglob("*.cgb")}
    twins = [c for c in (with_cgb or top) if c.stem in compiled]
    if len(twins) == 1:
        return twins[0]
    if len(top) == 1:
        return top[0]
    starts = [c for c in top if "@StartRule" in c.read_text(encoding="utf-8", errors="replace")]
    if len(starts) >= 1:
        return starts[0]
    raise InputError(f"'{path}' has several rule files; choose one with --rule "
                     f"({', '.join(str(c.relative_to(root)) for c in top)})")
