"""The package list, found rather than written; pyproject.toml holds the rest of the build.

Every straylight* package under straylight/ is found, plus the two data packages mapped from
folders outside it (straylight._config from config/, straylight._workflow from workflow/; their
files: pyproject.toml's package-data).  pyproject.toml's [tool.setuptools] takes either a found
list (packages.find, which only sees folders under straylight/) or a written one, not a found
list with mapped packages added: hence this file.
"""

from setuptools import find_packages, setup

MAPPED = {"straylight._config": "config", "straylight._workflow": "workflow"}

setup(
    packages=find_packages(include=["straylight", "straylight.*"]) + list(MAPPED),
    package_dir=MAPPED,
)
