"""The build's one step pyproject.toml cannot say: the example scenes (scenes/, their meshes and textures) go into
the wheel as raycast_phong/data/scenes, so `raycast-phong scene --example NAME` and the built-in default scene work
from a wheel installed anywhere. scenes/ stays their one home in the source tree (scene.schema.examples_folder
finds them in either place)."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildWithScenes(build_py):
    def run(self):
        super().run()
        source = Path(__file__).resolve().parent / "scenes"
        target = Path(self.build_lib) / "raycast_phong" / "data" / "scenes"
        if target.exists():
            shutil.rmtree(target)
        code = shutil.ignore_patterns("__pycache__", "*.pyc", "*.py")

        def ignored(folder: str, names: list[str]) -> set[str]:
            """Code, and beside the scenes the images a render wrote there (`render scenes/x.toml` writes x.png)."""
            skip = set(code(folder, names))
            if Path(folder) == source:
                skip |= {name for name in names if Path(name).suffix.lower() in (".png", ".exr")}
            return skip
        shutil.copytree(source, target, ignore=ignored)


setup(cmdclass={"build_py": BuildWithScenes})
