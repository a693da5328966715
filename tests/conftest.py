"""Options and fixtures shared by the whole test suite.

    pytest --update-references    rewrite the reference images instead of comparing against them
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from raycast_phong import read_layer, write_image


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--update-references", action="store_true", default=False,
                     help="Rewrite the reference images (tests/*/references/*.exr) from the current renderer; "
                          "view them before committing.")


class ReferenceImages:
    """The reference EXRs in one folder: read them, or rewrite them when --update-references is given."""

    def __init__(self, folder: Path, update: bool):
        self.folder = folder
        self.update = update

    def load_or_update(self, name: str, image: np.ndarray) -> np.ndarray:
        """The reference `name` as (H, W, 3) float32; in update mode `image` is written first.

        A missing reference fails the test (never passes silently) and says how to make one.
        """
        path = self.folder / name
        if self.update:
            self.folder.mkdir(parents=True, exist_ok=True)
            write_image(path, image)  # EXR: float32, zip-compressed, unclamped
        elif not path.is_file():
            pytest.fail(f"no reference image {path}; render it with `pytest {self.folder.parent} "
                        "--update-references`, look at it, and commit it", pytrace=False)
        # Read back even right after writing, so update runs also go through the EXR round trip.
        return read_layer(path)


@pytest.fixture
def references(request: pytest.FixtureRequest) -> ReferenceImages:
    """Reference images in the `references/` folder beside the requesting test module."""
    return ReferenceImages(Path(request.path).parent / "references",
                           update=request.config.getoption("--update-references"))
