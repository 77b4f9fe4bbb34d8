"""Sphinx configuration of the API reference (docs/api/).

Build: ``python -m sphinx -W --keep-going -b html docs/api docs/api/_build`` (``make docs``;
``tests/test_api_reference.py`` builds it into a temporary folder).  The pages document the
names ``straylight.__all__`` states, from their numpydoc docstrings; the package is imported from
the environment (``pip install -e ".[docs]"``).
"""

import straylight

project = "straylight"
author = "straylight developers"
copyright = "straylight developers"
release = straylight.__version__
version = release

extensions = ["sphinx.ext.autodoc", "numpydoc"]

# numpydoc renders the Parameters / Returns sections; the signatures' annotations would repeat
# them, so they are left out of the signatures
autodoc_typehints = "none"
autodoc_member_order = "bysource"
# the classes' members are documented by autodoc's :members: on each page
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False

exclude_patterns = ["_build"]
html_theme = "alabaster"
html_static_path: list[str] = []
