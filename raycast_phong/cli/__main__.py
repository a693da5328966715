"""python -m raycast_phong.cli: the raycast-phong command."""

from . import main

main()
