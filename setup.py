"""The package list, found: setuptools' ``packages.find`` in pyproject.toml cannot name a folder
outside ``imitate/`` as a sub-package, and envs/ and models/ install as ``imitate.envs`` and
``imitate.models`` (``package-dir`` in pyproject.toml). Everything else is in pyproject.toml."""

from setuptools import find_namespace_packages, setup

# Namespace packages too: a task's suites/ folder holds data only (the suites' .toml files).
setup(packages=[*find_namespace_packages(include=["imitate", "imitate.*"]),
                "imitate.envs", "imitate.models",
                *(f"imitate.envs.{name}" for name in find_namespace_packages(where="envs"))])
