"""Sky and aerial perspective from orbit to the ground, for Cycles and EEVEE.

Blender's Nishita sky stops at 60 km; this one is a single-scattering model of
an exponential Rayleigh + Mie atmosphere evaluated in node maths at any
altitude: the world shader gives the sky seen from the camera (blue above a
ground camera, the lit limb from orbit, black in space), the planet material
mixes the haze between the camera and the ground (aerial perspective).

Optical depths along a ray use the Chapman grazing-incidence function in
Christian Schüler's closed form ("An Approximation to the Chapman
Grazing-Incidence Function for Atmospheric Scattering", GPU Pro 3, 2012):
for a point at radius r, scale height H and direction cosine mu to the
vertical, optical depth / (beta * H) is
    U(r, mu) = c / (1 + c mu) * exp(-(r - R) / H),  c = sqrt(pi/2 * r / H)
upwards, and 2 sqrt(pi/2 * x0) exp((R - r0) / H) - U(r, -mu) downwards (r0:
the ray's closest approach to the centre, x0 = r0 / H).  Light scattered
towards the camera is E * sum(beta_k P_k(angle) tau_k) / tau * (1 - exp(-tau))
times the sun's transmittance to the scattering point.

Per-frame inputs (camera and sun in planet space, the anchor) are named
nodes that update() writes before every render.
"""
import math
import struct

import bpy

from . import compat, runtime
from . import nodes as node_maths

WORLD_PREFIX = "PlanetLOD sky "

# scattering coefficients (1/m) at the surface and scale heights (m)
ATMOSPHERES = {
    "EARTH": dict(rayleigh=(5.8e-6, 13.5e-6, 33.1e-6), rayleigh_height=8000.0,
                  mie=(21e-6, 21e-6, 21e-6), mie_height=1200.0, mie_g=0.76, gain=1.0, sky_gain=2.0),
    # thin CO2 with suspended dust: a butterscotch day sky, blue around the sun
    # at dusk (dust scatters forward and absorbs blue)
    "MARS": dict(rayleigh=(0.2e-6, 0.45e-6, 1.1e-6), rayleigh_height=11000.0,
                 mie=(9e-6, 6e-6, 3.5e-6), mie_height=11000.0, mie_g=0.65, gain=1.0, sky_gain=2.0),
}
ATMOSPHERE_ITEMS = [("NONE", "None", "No atmosphere: a black sky (Moon, asteroids)"),
                    ("EARTH", "Earth", "Rayleigh + Mie, scale heights 8 km and 1.2 km"),
                    ("MARS", "Mars-like", "Thin and dusty")]

INPUTS = ("plod_camera", "plod_sun", "plod_anchor")


def params(settings):
    """The atmosphere of a planet's settings (None: no atmosphere)."""
    base = ATMOSPHERES.get(settings.atmosphere)
    if base is None:
        return None
    density = max(settings.atmosphere_density, 0.0)
    if density == 0.0:
        return None
    values = dict(base)
    values["rayleigh"] = tuple(c * density for c in base["rayleigh"])
    values["mie"] = tuple(c * density for c in base["mie"])
    values["radius"] = settings.radius
    return values


# ---- node maths ------------------------------------------------------------------

def _up_term(b, r, mu, radius, height):
    """U(r, mu) for mu >= 0 (scalar Exprs).  Points below the radius count as on
    it: a coarse LOD's flat triangles sag kilometres below it (seen from afar),
    where exp(-altitude / 1.2 km) would turn the haze opaque."""
    c = b.sqrt(r * (math.pi / 2.0 / height))
    altitude = (r - radius) * (-1.0 / height)
    return c / (c * mu + 1.0) * b.exp(b.minimum(altitude, 0.0))


def _grazing(b, r0, radius, height, limit=30.0):
    """2 sqrt(pi/2 x0) exp((R - r0)/H): a whole ray through its closest approach
    (exponent capped at `limit`: a ray that meets the planet is opaque anyway)."""
    return b.sqrt(r0 * (math.pi / 2.0 / height)) * 2.0 * \
        b.exp(b.minimum((r0 - radius) * (-1.0 / height), limit))


def _to_space(b, r, mu, r0, radius, height):
    """Optical depth / (beta H) from radius r along a direction of cosine mu to space."""
    down = b.less(mu, 0.0)                      # 1 below the horizon
    sign = 1.0 - down * 2.0
    mu_abs = b.math("ABSOLUTE", mu)
    return sign * _up_term(b, r, mu_abs, radius, height) + down * _grazing(b, r0, radius, height)


def _phases(b, cos_angle, g):
    rayleigh = (cos_angle * cos_angle + 1.0) * (3.0 / (16.0 * math.pi))
    g2 = g * g
    denom = b.power(b.maximum(cos_angle * (-2.0 * g) + (1.0 + g2), 1e-4), 1.5)
    mie = (cos_angle * cos_angle + 1.0) * (3.0 / (8.0 * math.pi) * (1.0 - g2) / (2.0 + g2)) / denom
    return rayleigh, mie


def _scatter(b, atm, depth_r, depth_m, cos_sun, sun_depth_r, sun_depth_m, strength):
    """(radiance vector, transmittance vector) of light scattered along a path whose
    Rayleigh / Mie depths (over beta H) are depth_r / depth_m."""
    beta_r, beta_m = atm["rayleigh"], atm["mie"]
    h_r, h_m = atm["rayleigh_height"], atm["mie_height"]
    tau_r = b.const(tuple(c * h_r for c in beta_r)) * depth_r
    tau_m = b.const(tuple(c * h_m * 1.11 for c in beta_m)) * depth_m  # Mie extinction
    tau = b.maximum(tau_r + tau_m, (1e-7, 1e-7, 1e-7))
    phase_r, phase_m = _phases(b, cos_sun, atm["mie_g"])
    scattered = tau_r * phase_r + b.const(tuple(c * h_m for c in beta_m)) * depth_m * phase_m
    transmittance = b.vexp(-tau)
    sun_tau = b.const(tuple(c * h_r for c in beta_r)) * sun_depth_r + \
        b.const(tuple(c * h_m * 1.11 for c in beta_m)) * sun_depth_m
    sunlight = b.vexp(-sun_tau) * strength
    radiance = scattered / tau * ((1.0, 1.0, 1.0) - transmittance) * sunlight * atm["gain"]
    return radiance, transmittance


def _sun_depths(b, atm, point):
    """Depths (over beta H) from `point` (planet space) towards the sun."""
    sun = b.input_vector("plod_sun", (0.0, 0.0, 1.0))
    r = b.length(point)
    mu = b.dot(point / r, sun)
    r0 = r * b.sqrt(b.maximum(1.0 - mu * mu, 0.0))
    radius = atm["radius"]
    return (_to_space(b, r, mu, r0, radius, atm["rayleigh_height"]),
            _to_space(b, r, mu, r0, radius, atm["mie_height"]), sun)


def build_world(world, atm, strength=1.0):
    """The sky world: the atmosphere seen along each camera ray (black without one)."""
    compat.use_node_tree(world)
    # the sky changes every frame with the camera: Cycles' world importance map
    # would be rebuilt per frame (seconds); the sun lamp lights the ground
    world.cycles.sampling_method = 'NONE'
    tree = world.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputWorld")
    out.location = (400, 0)
    background = tree.nodes.new("ShaderNodeBackground")
    background.location = (200, 0)
    tree.links.new(background.outputs[0], out.inputs["Surface"])
    if atm is None:
        background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        return world
    b = node_maths.Builder(tree)
    coords = b.node("ShaderNodeTexCoord")
    d = b.normalize(b.socket(coords.outputs["Generated"]))
    camera = b.input_vector("plod_camera", (0.0, 0.0, atm["radius"] + 2.0))
    r = b.length(camera)
    mu = b.dot(camera / r, d)
    r0 = r * b.sqrt(b.maximum(1.0 - mu * mu, 0.0))
    radius = atm["radius"]
    depth_r = _to_space(b, r, mu, r0, radius, atm["rayleigh_height"])
    depth_m = _to_space(b, r, mu, r0, radius, atm["mie_height"])
    # the sun's light reaches the ray where it scatters most: the closest
    # approach to the planet (the limb seen from orbit), or the camera
    along = b.maximum(-(r * mu), 0.0)
    point = camera + d * along
    sun_r, sun_m, sun = _sun_depths(b, atm, point)
    energy = b.input_value("plod_sun_strength", strength)
    radiance, transmittance = _scatter(b, atm, depth_r, depth_m, b.dot(d, sun), sun_r, sun_m,
                                       energy)
    # the sun's disk (three times its size, so it shows at small resolutions)
    # (camera rays only: without a world importance map, diffuse bounces that
    # hit it by chance would be fireflies; the sun lamp lights the ground)
    disk = b.smoothstep(math.cos(math.radians(0.8)), math.cos(math.radians(0.7)), b.dot(d, sun))
    light_path = b.node("ShaderNodeLightPath")
    disk = disk * b.socket(light_path.outputs["Is Camera Ray"], vector=False)
    radiance = radiance * atm["sky_gain"] + transmittance * (disk * energy * 40.0)
    b.link(radiance, background.inputs["Color"])
    return world


def aerial_perspective(b, atm, surface):
    """Shader socket: `surface` seen through the air between the camera and the
    shading point (haze added, the surface dimmed by the transmittance)."""
    geometry = b.node("ShaderNodeNewGeometry")
    anchor = b.input_vector("plod_anchor")
    camera = b.input_vector("plod_camera", (0.0, 0.0, atm["radius"] + 2.0))
    point = b.socket(geometry.outputs["Position"]) + anchor
    view = point - camera
    distance = b.maximum(b.length(view), 1e-3)
    d = view / distance
    r_c, r_p = b.length(camera), b.length(point)
    mu_c, mu_p = b.dot(camera / r_c, d), b.dot(point / r_p, d)
    r0 = r_c * b.sqrt(b.maximum(1.0 - mu_c * mu_c, 0.0))
    radius = atm["radius"]
    depths = []
    down_c, down_p = b.less(mu_c, 0.0), b.less(mu_p, 0.0)
    for height in (atm["rayleigh_height"], atm["mie_height"]):
        # to_space(camera) - to_space(point), written so that the grazing term
        # (huge for rays that would hit the planet) only enters when the ray
        # passes its closest approach between the two (it cancels otherwise)
        up_c = _up_term(b, r_c, b.math("ABSOLUTE", mu_c), radius, height) * (1.0 - down_c * 2.0)
        up_p = _up_term(b, r_p, b.math("ABSOLUTE", mu_p), radius, height) * (1.0 - down_p * 2.0)
        crossing = b.math("ABSOLUTE", down_c - down_p)
        # (a ray that reaches the ground past its closest approach passed above
        # the radius there, except on the flat triangles of a coarse LOD, which
        # sag below it: count those as at the radius)
        segment = up_c - up_p + crossing * _grazing(b, r0, radius, height, limit=0.0)
        depths.append(b.maximum(segment, 0.0))
    sun_r, sun_m, sun = _sun_depths(b, atm, point)
    energy = b.input_value("plod_sun_strength", 1.0)
    radiance, transmittance = _scatter(b, atm, depths[0], depths[1], b.dot(d, sun), sun_r, sun_m,
                                       energy)
    haze = b.dot(transmittance, (0.3, 0.6, 0.1))  # luminance-weighted
    fog = 1.0 - haze
    emission = b.node("ShaderNodeEmission")
    b.link(radiance / b.maximum(fog, 1e-4), emission.inputs["Color"])
    mix = b.node("ShaderNodeMixShader")
    b.link(fog, mix.inputs["Fac"])
    b.links.new(surface, mix.inputs[1])
    b.links.new(emission.outputs[0], mix.inputs[2])
    return mix.outputs[0]


# ---- per-frame inputs ----------------------------------------------------------

def sun_of(scene):
    """(direction to the sun in world space, strength) of the scene's first sun lamp."""
    for obj in scene.objects:
        if obj.type == 'LIGHT' and obj.data.type == 'SUN' and not obj.hide_render:
            axis = obj.matrix_world.to_3x3() @ __import__("mathutils").Vector((0.0, 0.0, 1.0))
            return tuple(axis.normalized()), obj.data.energy
    return None, 1.0


def _as_float32(value):
    return struct.unpack("f", struct.pack("f", value))[0]


def _set_socket(socket, value):
    # each write re-evaluates the node tree (about 1 ms); most refreshes
    # change only the camera
    value = _as_float32(value)
    if socket.default_value != value:
        socket.default_value = value


def _set_inputs(tree, values):
    if tree is None:
        return
    for name, value in values.items():
        node = tree.nodes.get(name)
        if node is None:
            continue
        if node.type == 'VALUE':
            _set_socket(node.outputs[0], value)
        else:
            for i in range(3):
                _set_socket(node.inputs[i], value[i])


def update(obj, scene, camera_matrix):
    """Writes the camera (planet space, from the LOD camera's row-major matrix),
    the sun and the anchor into the planet's material and sky world."""
    camera = tuple(camera_matrix[i][3] for i in range(3))
    sun, strength = sun_of(scene)
    if sun is None:  # no sun lamp: light the sky from above the camera
        length = math.sqrt(sum(c * c for c in camera)) or 1.0
        sun = tuple(c / length for c in camera)
    anchor = runtime.anchor(obj)
    values = {"plod_camera": camera, "plod_sun": sun, "plod_anchor": anchor,
              "plod_sun_strength": strength, "plod_detail_offset": runtime.detail_offset(anchor)}
    for material in obj.data.materials:
        if material is not None and compat.has_node_tree(material):
            _set_inputs(material.node_tree, values)
    world = bpy.data.worlds.get(WORLD_PREFIX + obj.name)
    if world is not None and compat.has_node_tree(world):
        _set_inputs(world.node_tree, values)


def ensure_world(obj, scene, assign=False):
    """The planet's sky world (rebuilt when the atmosphere changed); `assign`
    makes it the scene's world."""
    s = obj.planet_lod
    atm = params(s)
    name = WORLD_PREFIX + obj.name
    world = bpy.data.worlds.get(name) or bpy.data.worlds.new(name)
    key = repr((atm, s.radius))
    if world.get("planet_lod_key") != key:
        build_world(world, atm)
        world["planet_lod_key"] = key
    if assign and scene is not None:
        scene.world = world
    return world
