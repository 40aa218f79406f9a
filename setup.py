"""Build hook: the shipped scenarios in ``layouts/`` (kept at the top level of the source
tree, see ARCHITECTURE.md) are copied into the wheel as ``warerover_phys/_layouts``, so an
installed package can run ``warerover run paper_homogeneous``. Metadata is in pyproject.toml.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithLayouts(build_py):
    def run(self):
        super().run()
        src = Path(__file__).resolve().parent / "layouts"
        dst = Path(self.build_lib) / "warerover_phys" / "_layouts"
        if dst.exists():
            shutil.rmtree(dst)
        # Real files only (no symlinks), YAML only.
        shutil.copytree(src, dst, symlinks=False,
                        ignore=lambda d, names: [n for n in names
                                                 if not (n.endswith((".yaml", ".yml"))
                                                         or (Path(d) / n).is_dir())])


setup(cmdclass={"build_py": BuildPyWithLayouts})
