"""facadeforge: facade imagery → semantic, procedural, editable 3D building models.

The public API; every CLI command calls one of these.
"""

from .engine import Rules, derive, derive_facade, derive_iter, load_rules, stats
from .errors import (
    DerivationError,
    FacadeForgeError,
    InputError,
    RuleError,
    RuleSyntaxError,
)
from .model import Labels, Material, Model, Part, Scope, Shape

__version__ = "0.1.0"

__all__ = [
    "DerivationError", "FacadeForgeError", "InputError", "Labels", "Material", "Model", "Part",
    "RuleError", "RuleSyntaxError", "Rules", "Scope", "Shape", "derive", "derive_facade", "derive_iter", "export",
    "load_rules", "parse", "reconstruct", "render", "stats",
]


def reconstruct(photo, **options):
    """Photo → shape tree, CGA rules and textured 3D model (Müller 2007); see
    :func:`facadeforge.reconstruct.reconstruct` for the options."""
    from .reconstruction import reconstruct as _reconstruct

    return _reconstruct(photo, **options)


def parse(photo, **options):
    """Photo → best derivation of a parse grammar (Simon 2011 ch. 4–5); see
    :func:`facadeforge.parsing.parse.parse` for the options."""
    from .parsing.parse import parse as _parse

    return _parse(photo, **options)


def export(models, path, **options):
    """Write models to ``path``; the format follows the suffix (see ``exchange.EXPORTERS``)."""
    from .exchange import export as _export

    return _export(models, path, **options)


def render(models_or_path, out_png, **options):
    """CPU preview render of models (or of a .glb/.obj file) to a PNG."""
    from .exchange import render as _render

    if isinstance(models_or_path, (str, bytes)) or hasattr(models_or_path, "__fspath__"):
        return _render.render_file(models_or_path, out_png, **options)
    return _render.render_preview(models_or_path, out_png, **options)
