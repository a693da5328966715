"""The raycast-phong command line: parses and prints; the package does the work."""

from .commands import app

__all__ = ["app"]
