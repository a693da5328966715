"""`python cli.py …` from a checkout: the same app as the installed `raycast-phong` command.

The app itself lives in the package (raycast_phong/cli/, one module per command group), so installing
raycast-phong adds no top-level module named `cli` that would shadow another on the path.
"""

from raycast_phong.cli import app, main  # noqa: F401  (app: the typer app, for whoever imports it)

if __name__ == "__main__":
    main()
