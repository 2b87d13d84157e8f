"""Version differences stay in addon/planet_lod/compat.py: the rest of the add-on,
the Blender-side tests and the tools neither test Blender's version nor use a
name that one of the supported Blenders (3.4, 4.2, 4.5, 5.0) refuses."""
import glob
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# name -> what to use instead (compat.py)
REFUSED = {
    r"bpy\.app\.version\b": "a helper or constant in compat.py",
    r"[\"']Specular[\"']": "compat.set_principled_specular (renamed in 4.0)",
    r"3D_UNIFORM_COLOR": "compat.UNIFORM_COLOR_SHADER (an error from 4.0)",
    r"loop_total": "compat.set_triangle_topology (read-only from 3.6)",
    r"use_auto_smooth|auto_smooth_angle": "the planet_normal attribute (auto smooth is gone in 4.1)",
    r"calc_normals_split": "compat.calc_loop_normals (gone in 4.1)",
    r"action\.fcurves": "compat.action_fcurves (gone in 5.0)",
    r"BLENDER_EEVEE_NEXT": "compat.render_engine / compat.eevee_engine",
}


def sources():
    files = glob.glob(os.path.join(ROOT, "addon", "planet_lod", "*.py"))
    files += glob.glob(os.path.join(ROOT, "tests", "blender", "*.py"))
    files += glob.glob(os.path.join(ROOT, "tools", "*.py"))
    return [f for f in sorted(files) if os.path.basename(f) != "compat.py"]


def test_version_differences_only_in_compat():
    found = []
    for path in sources():
        with open(path) as f:
            for number, line in enumerate(f, 1):
                code = line.split("#", 1)[0]
                for pattern, instead in REFUSED.items():
                    if re.search(pattern, code):
                        found.append(f"{os.path.relpath(path, ROOT)}:{number}: "
                                     f"{line.strip()}  -> use {instead}")
    assert not found, "\n".join(found)
