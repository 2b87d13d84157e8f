"""The code's layout rules, checked statically (no Blender, no build):

* the add-on's modules import one way: each imports only add-on modules
  that come before it in the order addon/planet_lod/__init__.py imports
  them (runtime state, then the scene's sky and materials, the cameras,
  placement, the refresh, the handlers, then the preview, operators and
  panels), at module level and inside functions alike;
* no add-on module is longer than MAX_ADDON_LINES;
* the `planetlod` package is bpy-free: none of its modules imports Blender's
  modules or the add-on;
* bench/, tools/, tests/ and farm/ reach the checkout without editing
  sys.path or loading files by path (README, "Imports without path edits")."""
import ast
import glob
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ADDON = os.path.join(ROOT, "addon", "planet_lod")


def parse(path):
    with open(path, encoding="utf-8") as f:
        return ast.parse(f.read(), filename=path)


def declared_order():
    """The add-on's modules in the order its __init__.py imports them."""
    for node in ast.walk(parse(os.path.join(ADDON, "__init__.py"))):
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module is None:
            return [alias.name for alias in node.names]
    raise AssertionError("addon/planet_lod/__init__.py has no `from . import (...)`")


def addon_imports(path):
    """(line, module) of every add-on module `path` imports, nested imports included."""
    found = []
    for node in ast.walk(parse(path)):
        if not isinstance(node, ast.ImportFrom) or node.level != 1:
            continue
        if node.module is None:  # from . import a, b
            found += [(node.lineno, alias.name) for alias in node.names]
        else:  # from .a import b
            found.append((node.lineno, node.module.split(".")[0]))
    return found


def test_every_addon_module_is_in_the_declared_order():
    order = declared_order()
    modules = sorted(os.path.splitext(os.path.basename(p))[0]
                     for p in glob.glob(os.path.join(ADDON, "*.py")))
    assert sorted(order) == [m for m in modules if m != "__init__"]


def test_addon_imports_run_one_way():
    order = declared_order()
    rank = {name: index for index, name in enumerate(order)}
    upward = []
    for name in order:
        for line, imported in addon_imports(os.path.join(ADDON, name + ".py")):
            if rank.get(imported, len(order)) >= rank[name]:
                upward.append(f"{name}.py:{line} imports {imported}")
    assert not upward, "imports against the order of __init__.py: " + "; ".join(upward)


def test_the_order_check_sees_nested_imports(tmp_path):
    path = tmp_path / "module.py"
    path.write_text("from . import a\n\ndef f():\n    from .b import c\n")
    assert addon_imports(str(path)) == [(1, "a"), (4, "b")]


# A module past this is doing more than one job: split it by job.
MAX_ADDON_LINES = 400
# Longer still, each with the lines it may not grow past until it is split.
def test_addon_modules_stay_small():
    long = []
    for path in sorted(glob.glob(os.path.join(ADDON, "*.py"))):
        name = os.path.splitext(os.path.basename(path))[0]
        with open(path, encoding="utf-8") as f:
            lines = sum(1 for _ in f)
        if lines > MAX_ADDON_LINES:
            long.append(f"{name}.py: {lines} lines")
    assert not long, f"add-on modules over {MAX_ADDON_LINES} lines: " + "; ".join(long)


BLENDER_MODULES = {"bpy", "bpy_extras", "bmesh", "mathutils", "gpu", "gpu_extras", "bl_ui",
                   "addon_utils", "planet_lod"}


def imported_modules(path):
    """(line, top-level module) of every absolute import in a Python file."""
    found = []
    for node in ast.walk(parse(path)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name.split(".")[0]) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module.split(".")[0]))
    return found


def test_planetlod_is_bpy_free():
    offenders = []
    for path in sorted(glob.glob(os.path.join(ROOT, "planetlod", "*.py"))):
        offenders += [f"{os.path.relpath(path, ROOT)}:{line} imports {module}"
                      for line, module in imported_modules(path) if module in BLENDER_MODULES]
    assert not offenders, "planetlod/ must run without Blender: " + "; ".join(offenders)


def test_the_bpy_check_sees_each_form(tmp_path):
    path = tmp_path / "module.py"
    path.write_text("import numpy\nimport bpy.types\n\ndef f():\n    from mathutils import Matrix\n")
    assert [m for _, m in imported_modules(str(path)) if m in BLENDER_MODULES] == \
        ["bpy", "mathutils"]


PATH_EDITS = {"insert", "append", "extend", "remove", "clear"}


def path_edits(path):
    """(line, what) of each sys.path edit or load-by-path in a Python file."""
    found = []
    for node in ast.walk(parse(path)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            owner = node.func.value
            if (node.func.attr in PATH_EDITS and isinstance(owner, ast.Attribute)
                    and owner.attr == "path" and isinstance(owner.value, ast.Name)
                    and owner.value.id == "sys"):
                found.append((node.lineno, f"sys.path.{node.func.attr}"))
            elif node.func.attr in ("spec_from_file_location", "addsitedir"):
                found.append((node.lineno, node.func.attr))
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AugAssign) else [])
        for target in targets:
            if isinstance(target, ast.Subscript):
                target = target.value
            if (isinstance(target, ast.Attribute) and target.attr == "path"
                    and isinstance(target.value, ast.Name) and target.value.id == "sys"):
                found.append((node.lineno, "sys.path assignment"))
    return found


# Python embedded in shell scripts (heredocs, -c)
SHELL_PATH_EDIT = re.compile(r"sys\.path\.(insert|append|extend)|sys\.path\s*[+]?=|"
                             r"spec_from_file_location|addsitedir")


def test_no_sys_path_edits_in_bench_tools_tests_farm():
    offenders = []
    for folder in ("bench", "tools", "tests", "farm"):
        for path in glob.glob(os.path.join(ROOT, folder, "**", "*.py"), recursive=True):
            offenders += [f"{os.path.relpath(path, ROOT)}:{line} {what}"
                          for line, what in path_edits(path)]
        for path in glob.glob(os.path.join(ROOT, folder, "**", "*.sh"), recursive=True):
            with open(path, encoding="utf-8") as f:
                for line, text in enumerate(f, 1):
                    if SHELL_PATH_EDIT.search(text) and not text.lstrip().startswith("#"):
                        offenders.append(f"{os.path.relpath(path, ROOT)}:{line} {text.strip()}")
    assert not offenders, "path edits (use the package, python3 -m, PYTHONPATH): " + \
        "; ".join(offenders)


def test_the_path_check_sees_each_form(tmp_path):
    path = tmp_path / "script.py"
    path.write_text("import sys, importlib.util\n"
                    "sys.path.insert(0, 'x')\n"
                    "sys.path.append('x')\n"
                    "sys.path[:0] = ['x']\n"
                    "sys.path += ['x']\n"
                    "importlib.util.spec_from_file_location('m', 'm.py')\n")
    assert sorted(line for line, _ in path_edits(str(path))) == [2, 3, 4, 5, 6]
