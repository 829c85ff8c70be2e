"""tests/testproject is a user's project of its own: a technique, a scene, goldens and a test
file that uses only pipegen's pytest plugin and ``pipegen.testing``.

Our suite does not collect it here (inside the repository, our pyproject.toml's options and
tests/conftest.py's backend guards would apply to it): tests/test_plugin.py copies the project,
without this file, into a temporary folder and runs pytest there, as a user would.  Refresh its
goldens with ``python tests/test_plugin.py --update-goldens``.
"""

collect_ignore_glob = ["*"]
