"""The module imports from the build tree and reports the project's version."""
import os
import re

import fabrik


def test_version_is_the_projects():
    cmake = open(os.path.join(os.environ["FABRIK_SOURCE_DIR"], "CMakeLists.txt")).read()
    declared = re.search(r"project\(fabrikd VERSION ([0-9.]+)", cmake).group(1)
    assert fabrik.__version__ == declared
