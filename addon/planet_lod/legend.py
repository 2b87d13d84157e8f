"""The legend of Show Levels: a swatch per refinement level, drawn in the 3D
view's corner while a planet shows its levels, in the preview's colours
(shaders/planet_preview_frag.glsl, level_colour), with what a level means in
the planet's LOD method."""
import math

import bpy
import gpu
from gpu_extras.batch import batch_for_shader

from . import runtime
from .core import planets

SWATCH = 12  # pixels, at interface scale 1


def level_colour(level):
    """The preview's colour of a level (sRGB, as the shader's level_colour)."""
    hue = (level * 0.137) % 1.0
    rgb = []
    for shift in (0.0, 2.0 / 3.0, 1.0 / 3.0):
        k = min(max(abs(((hue + shift) % 1.0) * 6.0 - 3.0) - 1.0, 0.0), 1.0)
        rgb.append(0.15 + 0.85 * k)
    return tuple(rgb)


def levels_shown(scene):
    """(planet name, deepest level, what a level means) of the first planet
    showing its levels, or None."""
    for obj in runtime.planet_objects(scene):
        s = obj.planet_lod
        if s.show_levels and s.gpu_preview:
            st = runtime.existing_state(obj)
            depth = int(st.stats.get("max_level", 0)) if st is not None and st.stats else 0
            if s.lod_method == 'GEOMIPMAP':  # mip levels 0..n of the tiles' grid
                depth = int(s.as_dict()["template_level"])
            meaning = planets.LEVEL_MEANING.get(s.lod_method, planets.LEVEL_MEANING["HRTMR"])
            return obj.name, max(depth, 1), meaning
    return None


def _shader():
    for name in ('UNIFORM_COLOR', '2D_UNIFORM_COLOR'):
        try:
            return gpu.shader.from_builtin(name)
        except (ValueError, SystemError):
            continue
    return None


def draw_legend():
    import blf
    context = bpy.context
    scene = getattr(context, "scene", None)
    shown = levels_shown(scene) if scene is not None else None
    shader = _shader() if shown else None
    if shader is None:
        return
    name, depth, meaning = shown
    scale = context.preferences.system.ui_scale
    size = SWATCH * scale
    x = 20 * scale
    y = 40 * scale
    levels = list(range(depth + 1))
    # a long list is shown every few levels so it fits the view
    room = max(int((context.region.height - 80 * scale) / (size + 2 * scale)), 2)
    step = max(1, math.ceil(len(levels) / room))
    gpu.state.blend_set('ALPHA')
    font = 0
    blf.size(font, int(11 * scale))  # Blender 3.4 on: no dpi argument
    blf.color(font, 1.0, 1.0, 1.0, 0.9)
    for row, level in enumerate(levels[::step]):
        top = y + row * (size + 2 * scale)
        corners = ((x, top), (x + size, top), (x + size, top + size), (x, top + size))
        batch = batch_for_shader(shader, 'TRI_FAN', {"pos": corners})
        shader.bind()
        shader.uniform_float("color", level_colour(level) + (1.0,))
        batch.draw(shader)
        blf.position(font, x + size + 6 * scale, top + 2 * scale, 0)
        blf.draw(font, f"level {level}")
    blf.position(font, x, y + (len(levels[::step])) * (size + 2 * scale) + 4 * scale, 0)
    blf.draw(font, f"{name}: {meaning}")
    gpu.state.blend_set('NONE')


_handles = {}


def register():
    _handles["legend"] = bpy.types.SpaceView3D.draw_handler_add(draw_legend, (), 'WINDOW',
                                                                'POST_PIXEL')


def unregister():
    handle = _handles.pop("legend", None)
    if handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(handle, 'WINDOW')
