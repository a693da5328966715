"""Options and fixtures shared by the whole test suite.

    pytest --update-references    rewrite the reference images instead of comparing against them

The option and the `assert_image_matches` / `image_references` fixtures come from raycast-phong's own pytest
plugin (raycast_phong/pytest_plugin.py, registered by the installed package's pytest11 entry point).
"""

from __future__ import annotations

pytest_plugins = ["pytester"]  # the plugin's own tests (tests/test_pytest_plugin.py) run pytest inside pytest
