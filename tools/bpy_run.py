"""Runs a script written for `blender -b --python SCRIPT -- ARGS` with Blender as
a Python module (the `bpy` wheel), the way Blender would run it:

    VENV/bin/python tools/bpy_run.py SCRIPT [-- ARGS...]

`import bpy` comes first (it puts Blender's scripts/modules, with addon_utils,
on sys.path); the script then runs as __main__ with sys.argv ending in
"-- ARGS" as under Blender.  Exit status as with --python-exit-code 1: 0, the
script's SystemExit code, or 1 on an exception.  The process ends with
os._exit after flushing Python's and C's output and removing Blender's
session temp folder (what the module's own shutdown would do): that shutdown
can hang after a .blend was opened (seen with bpy 4.5), and nothing is left to
save at that point.
"""
import ctypes
import os
import runpy
import shutil
import sys
import traceback


def remove_session_tempdir():
    bpy = sys.modules.get("bpy")
    folder = os.path.normpath(bpy.app.tempdir) if bpy is not None else ""
    if os.path.basename(folder).startswith("blender_"):
        shutil.rmtree(folder, ignore_errors=True)


def main():
    if len(sys.argv) < 2:
        print("usage: python tools/bpy_run.py SCRIPT [-- ARGS...]", file=sys.stderr)
        return 2
    script = os.path.abspath(sys.argv[1])
    rest = sys.argv[2:]
    if rest[:1] == ["--"]:
        rest = rest[1:]
    import bpy  # noqa: F401  (sets up Blender's module path)
    sys.argv = [script, "--"] + rest
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as exc:
        code = exc.code
        if code is None:
            return 0
        if isinstance(code, int):
            return code
        print(code, file=sys.stderr)
        return 1
    except BaseException:
        traceback.print_exc()
        return 1
    return 0


if __name__ == "__main__":
    status = main()
    remove_session_tempdir()
    sys.stdout.flush()
    sys.stderr.flush()
    ctypes.CDLL(None).fflush(None)
    os._exit(status)
