"""Options and output helpers shared by the commands (declared once, as in rasterio's rio)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

json_option = click.option(
    "--json", "as_json", is_flag=True,
    help="Print the results as JSON on stdout (SI units, frequencies in Hz) instead of tables.")

force_option = click.option(
    "--force", is_flag=True, help="Overwrite an existing output file.")


def check_output_path(path: str | Path | None, force: bool) -> Path | None:
    """Refuse to overwrite an existing file unless --force (exit 2 via OutputExistsError)."""
    from laminid_cli.errors import OutputExistsError

    if path is None:
        return None
    path = Path(path)
    if path.exists() and not force:
        raise OutputExistsError(f"{path}: file exists; use --force to overwrite it or choose "
                                "another name with -o")
    if not path.parent.exists():
        raise OutputExistsError(f"{path}: folder {path.parent} does not exist")
    return path


def _clean(obj):
    """JSON-safe copy: numpy scalars/arrays to Python, NaN/inf to None."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if np is not None and isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if np is not None and isinstance(obj, np.generic):
        return _clean(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def echo_json(obj) -> None:
    """Print ``obj`` as indented JSON on stdout (NaN written as null)."""
    click.echo(json.dumps(_clean(obj), indent=2))
