#!/usr/bin/python3
"""Fails if a Catch test case could not run under ctest.

catch_discover_tests turns each test case into a ctest entry that runs the
binary with the name as a test spec. A ';' splits the name into two entries
(CMake lists) and '*' or '\\' change the spec: such an entry matches no test
case, and Catch then passes with nothing run. So a name must avoid them.

  check_test_names.py TEST_EXECUTABLE...
"""
import subprocess
import sys

FORBIDDEN = ";*\\"


def main():
    bad = []
    listed = 0
    for exe in sys.argv[1:]:
        out = subprocess.run([exe, "--list-test-names-only"], capture_output=True, text=True,
                             timeout=60).stdout  # Catch exits with the count
        if not out.strip():
            bad.append(f"{exe}: lists no test case")
        for name in out.splitlines():
            if not name.strip():
                continue
            listed += 1
            if any(c in name for c in FORBIDDEN) or name != name.strip():
                bad.append(f"{exe}: {name!r}")
    for b in bad:
        print("cannot run under ctest (avoid ; * \\ and edge spaces in names):", b)
    print(f"{listed} test case names checked, {len(bad)} unusable")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
