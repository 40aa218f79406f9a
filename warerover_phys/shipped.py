"""The scenarios shipped with the package, found by bare name.

``warerover run paper_homogeneous`` (or ``load_scenario("paper_homogeneous")``) works from any
folder: a scenario argument that is not an existing file and has no folder part is looked up
among the shipped scenarios, first those packaged in the wheel (``warerover_phys/_layouts``),
then the source tree's ``layouts/`` folder.

>>> shipped_path("paper_homogeneous").name
'paper_homogeneous.yaml'
>>> "industrial" in shipped_names()
True
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["shipped_dirs", "shipped_names", "shipped_path", "resolve_scenario"]

_PACKAGE = Path(__file__).resolve().parent


def shipped_dirs() -> list[Path]:
    """Folders holding the shipped scenarios: packaged, then the source tree's."""
    return [d for d in (_PACKAGE / "_layouts", _PACKAGE.parent / "layouts") if d.is_dir()]


def shipped_names() -> list[str]:
    """Names of the shipped scenarios (``paper_homogeneous``, ...)."""
    return sorted({p.stem for d in shipped_dirs() for p in d.glob("*.yaml")})


def shipped_path(name: str) -> Path | None:
    """The file of shipped scenario ``name`` (with or without ``.yaml``), or None."""
    stem = name.removesuffix(".yaml").removesuffix(".yml")
    for d in shipped_dirs():
        for suffix in (".yaml", ".yml"):
            p = d / f"{stem}{suffix}"
            if p.is_file():
                return p
    return None


def resolve_scenario(path: str | Path) -> Path:
    """``path`` itself when it exists or names a folder; else the shipped scenario of that
    bare name, if there is one; else ``path`` unchanged (the reader reports it missing)."""
    p = Path(path)
    if p.exists() or len(p.parts) != 1:
        return p
    found = shipped_path(p.name)
    return found if found is not None else p
