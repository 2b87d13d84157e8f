#!/usr/bin/env python3
"""The Open Job Description runtime (openjd-cli, openjd-sessions from PyPI) in
a venv cached under ~/.cache/planetlod/openjd-<cli version>, for running the
farm's job templates (farm/openjd/) locally and in the tests:

    python3 tools/openjd_env.py install   # once (tools/run_tests.sh runs it)
    python3 tools/openjd_env.py openjd    # prints the openjd command's path
"""
import argparse
import os
import shutil
import subprocess
import sys

from tools.blender_versions import locked, base_python, cache_root

# Versions that install together (openjd-cli pins its openjd-sessions range).
OPENJD_CLI = "0.8.0"
OPENJD_SESSIONS = "0.13.0"


def venv_dir():
    return os.path.join(cache_root(), f"openjd-{OPENJD_CLI}")


def openjd():
    """The openjd command of the installed venv, or None."""
    path = os.path.join(venv_dir(), "bin", "openjd")
    complete = os.path.join(venv_dir(), ".complete")
    return path if os.path.isfile(path) and os.path.isfile(complete) else None


def install():
    """Creates the venv unless it exists; returns the openjd command."""
    root = cache_root()
    os.makedirs(root, exist_ok=True)
    with locked(os.path.join(root, ".lock")):
        if openjd():
            return openjd()
        final = venv_dir()
        # built where it runs (console scripts name the venv's python by its
        # path); .complete, written last, marks it usable
        shutil.rmtree(final, ignore_errors=True)
        python = base_python("3.11") or sys.executable
        subprocess.run([python, "-m", "venv", final], check=True)
        subprocess.run([os.path.join(final, "bin", "python"), "-m", "pip", "install", "--quiet",
                        "--disable-pip-version-check", f"openjd-cli=={OPENJD_CLI}",
                        f"openjd-sessions=={OPENJD_SESSIONS}"], check=True)
        with open(os.path.join(final, ".complete"), "w") as f:
            f.write(f"openjd-cli {OPENJD_CLI}\n")
        print(f"openjd_env: openjd-cli {OPENJD_CLI} ready in {final}", flush=True)
        return openjd()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("command", choices=["install", "openjd"])
    args = p.parse_args(argv)
    if args.command == "install":
        try:
            install()
        except (OSError, subprocess.SubprocessError) as exc:
            print(f"openjd_env: WARNING: the OpenJD runtime could not be installed ({exc}); "
                  "its tests will be skipped", file=sys.stderr, flush=True)
        return 0
    if openjd() is None:
        return 1
    print(openjd())
    return 0


if __name__ == "__main__":
    sys.exit(main())
