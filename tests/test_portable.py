"""The Python that runs on artists' machines (the add-on, the planetlod
package, the tools a user runs) is portable: no POSIX-only module, call or
file.  A POSIX-only module may be imported only in a branch that tests the
system (os.name / sys.platform), beside its Windows counterpart."""
import ast
import glob
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

USER_TOOLS = ("blender_versions.py", "bpy_run.py", "build_extension.py", "build_wheels.py",
              "descent_hash.py", "fill_coast.py", "flyby.py", "install_addon.py",
              "make_procedural_maps.py",
              "planetlod_resample.py")

POSIX_MODULES = {"fcntl", "resource", "pwd", "grp", "termios", "tty", "pty", "posix",
                 "crypt", "spwd", "syslog", "nis", "ossaudiodev", "readline"}
# os / signal names that do not exist on Windows
POSIX_CALLS = {"fork", "forkpty", "wait", "wait3", "wait4", "waitpid", "getuid", "geteuid",
               "getgid", "getegid", "setsid", "killpg", "getloadavg", "uname", "sysconf",
               "sched_getaffinity", "sched_setaffinity", "nice", "mkfifo", "getpgid",
               "SIGKILL", "SIGHUP", "SIGUSR1", "SIGUSR2", "SIGALRM", "SIGCHLD", "SIGQUIT",
               "alarm", "setitimer"}
POSIX_KEYWORDS = {"preexec_fn", "start_new_session", "pass_fds"}


def portable_sources():
    files = glob.glob(os.path.join(ROOT, "addon", "**", "*.py"), recursive=True)
    files += glob.glob(os.path.join(ROOT, "planetlod", "*.py"))
    files += [os.path.join(ROOT, "tools", name) for name in USER_TOOLS]
    return sorted(f for f in files if os.path.exists(f))


def _tests_system(node):
    """An `if` whose test reads os.name or sys.platform."""
    for sub in ast.walk(node.test):
        if isinstance(sub, ast.Attribute) and sub.attr in ("name", "platform") and \
                isinstance(sub.value, ast.Name) and sub.value.id in ("os", "sys"):
            return True
    return False


def posix_only_uses(path):
    with open(path, encoding="utf-8") as f:
        source = f.read()
    tree = ast.parse(source, path)
    guarded = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and _tests_system(node):
            for sub in ast.walk(node):
                guarded.add(id(sub))
    found = []
    for node in ast.walk(tree):
        where = f"{os.path.relpath(path, ROOT)}:{getattr(node, 'lineno', '?')}"
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            for name in names:
                if name.split(".")[0] in POSIX_MODULES and id(node) not in guarded:
                    found.append(f"{where} imports {name}")
        elif isinstance(node, ast.Attribute):
            if isinstance(node.value, ast.Name) and node.value.id in ("os", "signal") and \
                    node.attr in POSIX_CALLS and id(node) not in guarded:
                found.append(f"{where} uses {node.value.id}.{node.attr}")
        elif isinstance(node, ast.keyword) and node.arg in POSIX_KEYWORDS and \
                id(node) not in guarded:
            found.append(f"{where} passes {node.arg}=")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and \
                node.value.startswith(("/proc/", "/sys/", "/dev/shm")):
            found.append(f"{where} reads {node.value}")
    return found


def test_user_python_is_portable():
    files = portable_sources()
    assert len(files) > 20, files
    found = [use for path in files for use in posix_only_uses(path)]
    assert not found, "POSIX-only in portable Python:\n" + "\n".join(found)


def test_the_scan_finds_what_it_looks_for(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text(
        "import os\nimport fcntl\nimport subprocess\n"
        "pid = os.fork()\n"
        "subprocess.run(['x'], preexec_fn=None)\n"
        "open('/proc/self/status')\n"
        "if os.name == 'nt':\n    import msvcrt\nelse:\n    import fcntl as f2\n")
    found = posix_only_uses(str(sample))
    assert [use.split(" ", 1)[1] for use in found] == [
        "imports fcntl", "uses os.fork", "passes preexec_fn=", "reads /proc/self/status"], found


def test_core_opens_files_named_beyond_ascii(run_c_test, tmp_path, monkeypatch):
    """tests/c/test_paths.c: the grid, format-guess and GeoTIFF readers open
    UTF-8 names with accents and CJK (also run under Wine by test_wheels)."""
    monkeypatch.chdir(tmp_path)
    out = run_c_test("test_paths", ["image_raw.c", "geotiff.c", "image_buffer.c", "base.c",
                                    "status.c"])
    assert "paths C tests passed" in out
