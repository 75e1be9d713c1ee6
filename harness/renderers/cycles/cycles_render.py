"""cycles_render.py - render a reflcheck Cycles job (written by harness/cycles.c) in Blender 3.4.

Usage:
    blender -b --factory-startup [-t THREADS] -P harness/cycles_render.py -- JOB.json OUT.exr
    render_job(JOB.json, OUT.exr, threads) from another script in Blender: one job per call
    (worker.py renders many jobs in one Blender that way)

For every seed i in the job it renders once and writes the raw multilayer EXR OUT.cyc<i>.exr
(32-bit float, uncompressed) with these channels (harness/cycles.c renames them and averages the seeds):
    R G B A              full image: surfaces + the environment seen by camera rays; A = coverage
    diffuse.RGBA         (DiffDir + DiffInd) * DiffCol
    specular.RGBA        glossy passes when the job routes glossy to "specular"
    reflection.RGBA      glossy passes when the job routes glossy to "reflection"
    emission.RGBA        Emit
    background.RGBA      Env (the environment seen by camera rays; in no other layer)
    coverage.V           Alpha
    object.V             IndexOB - 1 (pass_index is object index + 1; background -1)
and OUT.timing.json with the build and render times in seconds and the width of the world's
importance map (world_map, 0 = none), which the log's last line repeats.
Any failure prints one line "cycles_render.py: error: ..." to stderr and exits with status 1.

Frame: the job is in reflcheck's canonical frame (right-handed, +Y up); Blender is Z-up,
so a canonical (x, y, z) becomes (x, -z, y), a proper rotation, which keeps triangle winding.
"""
import json
import math
import os
import sys
import time
import traceback

import bpy
from mathutils import Matrix, Vector


class JobError(Exception):
    pass


# The float vertex normals' attribute (setup_objects, exact_normals).
EXACT_NORMAL = "reflcheck_normal"


def to_blender(v):
    return Vector((v[0], -v[2], v[1]))


def need(d, key, where):
    if key not in d:
        raise JobError("%s: missing key '%s'; rewrite the job with reflcheck cycles-job" % (where, key))
    return d[key]


# ---------------------------------------------------------------- render settings


def setup_render(job):
    sc = bpy.context.scene
    sc.render.engine = 'CYCLES'
    cy = sc.cycles
    cy.device = 'CPU'
    cy.feature_set = 'SUPPORTED'
    cy.samples = int(need(job, "samples", "job"))
    # This Blender has no OpenImageDenoise: denoising on would fail the render.
    cy.use_denoising = False
    cy.use_adaptive_sampling = False
    cy.use_animated_seed = False
    cy.light_sampling_threshold = 0.0
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.film_exposure = 1.0
    # Width 1: samples jittered over the pixel by the box filter (an integral). Below 1 (a twin
    # rendered at k times the size, cycles.h): a point per sub-pixel, the model's sample
    # position; Blender ignores the width of a box filter (its sync sets 1, its UI hides the
    # field), so the point is a Gaussian of that width, Blender's narrowest (0.01 pixel).
    width = float(job.get("filter_width", 1.0))
    cy.pixel_filter_type = 'BOX' if width >= 1.0 else 'GAUSSIAN'
    cy.filter_width = width
    # Scrambling distance < 1 correlates pixels; 1 keeps the sampler unbiased.
    cy.auto_scrambling_distance = False
    cy.scrambling_distance = 1.0
    cy.use_guiding = False
    # One bounce (the default physics) so that a mirror (SHARP) closure sees the environment
    # and MIS keeps both halves of environment lighting; objects are invisible to secondary
    # rays unless the physics asks for inter-reflection, so a bounce can only reach the world.
    bounces = int(need(need(job, "physics", "job"), "bounces", "physics"))
    cy.max_bounces = bounces
    cy.diffuse_bounces = bounces
    cy.glossy_bounces = bounces
    cy.transmission_bounces = 0
    cy.volume_bounces = 0
    cy.transparent_max_bounces = 0
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    r = sc.render
    r.resolution_x = int(need(job, "width", "job"))
    r.resolution_y = int(need(job, "height", "job"))
    r.resolution_percentage = 100
    r.pixel_aspect_x = 1.0
    r.pixel_aspect_y = 1.0
    r.use_border = False
    # Transparent film: Combined excludes the background, which goes to the Env pass, so
    # coverage (alpha) and the environment are both available; R,G,B = Combined + Env.
    r.film_transparent = True
    r.use_persistent_data = False
    sc.frame_current = 1
    vs = sc.view_settings
    vs.view_transform = 'Standard'
    vs.look = 'None'
    vs.exposure = 0.0
    vs.gamma = 1.0
    vs.use_curve_mapping = False
    sc.sequencer_colorspace_settings.name = 'Linear'


def setup_camera(job):
    c = need(job, "camera", "job")
    eye = to_blender(need(c, "eye", "camera"))
    target = to_blender(need(c, "target", "camera"))
    up = to_blender(need(c, "up", "camera"))
    f = target - eye
    if f.length == 0.0:
        raise JobError("camera: eye equals target; move the camera target")
    f.normalize()
    r = f.cross(up)
    if r.length < 1e-6:  # up parallel to the view direction: no roll is defined
        raise JobError("camera: up is parallel to the view direction; change camera.up")
    r.normalize()
    u = r.cross(f)
    # Blender cameras look down local -Z with local +Y up; for up = canonical +Y this equals
    # (target - eye).to_track_quat('-Z', 'Y') and it honours any other up vector too.
    rot = Matrix((r, u, -f)).transposed()
    data = bpy.data.cameras.new("reflcheck_camera")
    data.type = 'PERSP'
    data.sensor_fit = 'HORIZONTAL'
    data.angle_x = float(need(c, "hfov", "camera"))
    data.shift_x = 0.0
    data.shift_y = 0.0
    data.clip_start = float(c.get("clip_start", 1e-3))
    data.clip_end = float(c.get("clip_end", 1e6))
    cam = bpy.data.objects.new("reflcheck_camera", data)
    cam.matrix_world = Matrix.Translation(eye) @ rot.to_4x4()
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam


def setup_lights(job):
    physics = need(job, "physics", "job")
    visibility = need(physics, "light_visibility", "physics")
    lights = need(job, "lights", "job")
    if len(visibility) != len(lights):
        raise JobError("physics.light_visibility: %d entries for %d lights" % (len(visibility), len(lights)))
    for i, l in enumerate(lights):
        where = "lights[%d]" % i
        kind = need(l, "type", where)
        if kind not in ("POINT", "SUN", "SPOT"):
            raise JobError("%s: unknown type '%s'" % (where, kind))
        data = bpy.data.lights.new("reflcheck_light_%d" % i, kind)
        data.energy = float(need(l, "energy", where))
        data.color = need(l, "color", where)
        shadows = bool(need(physics, "shadows", "physics"))
        if hasattr(data, "use_shadow"):
            data.use_shadow = shadows
        data.cycles.cast_shadow = shadows
        data.cycles.max_bounces = 1024
        if kind == "SUN":
            data.angle = 0.0
        else:
            data.shadow_soft_size = 0.0
        if kind == "SPOT":
            data.spot_size = float(need(l, "spot_size", where))
            data.spot_blend = float(need(l, "spot_blend", where))
        ob = bpy.data.objects.new("reflcheck_light_%d" % i, data)
        if kind in ("POINT", "SPOT"):
            ob.location = to_blender(need(l, "position", where))
        if kind in ("SUN", "SPOT"):
            d = to_blender(need(l, "direction", where))
            ob.rotation_mode = 'QUATERNION'
            ob.rotation_quaternion = d.to_track_quat('-Z', 'Y')
        # Which closures the lamp lights (the physics' light masks): Cycles skips an excluded
        # closure in the lamp's direct-light evaluation.
        vis = visibility[i]
        ob.visible_diffuse = bool(need(vis, "diffuse", "physics.light_visibility[%d]" % i))
        ob.visible_glossy = bool(need(vis, "glossy", "physics.light_visibility[%d]" % i))
        bpy.context.scene.collection.objects.link(ob)


def setup_world(job):
    env = need(job, "environment", "job")
    w = bpy.data.worlds.new("reflcheck_world")
    w.use_nodes = True
    nt = w.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new('ShaderNodeOutputWorld')
    bg = nt.nodes.new('ShaderNodeBackground')
    bg.inputs['Strength'].default_value = 1.0
    kind = need(env, "type", "environment")
    if kind == "none":
        bg.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
        bg.inputs['Strength'].default_value = 0.0
    elif kind == "constant":
        c = need(env, "radiance", "environment")
        bg.inputs['Color'].default_value = (c[0], c[1], c[2], 1.0)
    elif kind == "image":
        path = need(env, "path", "environment")
        try:
            img = bpy.data.images.load(path, check_existing=False)
        except RuntimeError as e:
            raise JobError("environment.path '%s': %s; check the scene's environment file" % (path, e))
        img.colorspace_settings.name = 'Linear'
        tex = nt.nodes.new('ShaderNodeTexEnvironment')
        tex.image = img
        tex.interpolation = 'Linear'
        tex.projection = 'EQUIRECTANGULAR'
        scale = nt.nodes.new('ShaderNodeVectorMath')
        scale.operation = 'MULTIPLY'
        scale.inputs[1].default_value = need(env, "scale", "environment")
        nt.links.new(tex.outputs['Color'], scale.inputs[0])
        nt.links.new(scale.outputs['Vector'], bg.inputs['Color'])
    else:
        raise JobError("environment.type '%s' unknown; expected none, constant or image" % kind)
    nt.links.new(bg.outputs['Background'], out.inputs['Surface'])
    vis = need(job, "world_visibility", "job")
    w.cycles_visibility.camera = True
    w.cycles_visibility.diffuse = bool(need(vis, "diffuse", "world_visibility"))
    w.cycles_visibility.glossy = bool(need(vis, "glossy", "world_visibility"))
    w.cycles_visibility.transmission = False
    w.cycles_visibility.scatter = False
    if not vis.get("light_sampling", True):
        # Nothing that samples lights can see the world (mirrors reach it by their bounce ray).
        w.cycles.sampling_method = 'NONE'
    elif kind == "image":
        # One map texel per texel of the image's detail: its width, or the job's map_resolution
        # (a cube map's 4 N, whose 16 x wider conversion holds no more); 'AUTOMATIC' builds a
        # larger map at some cost. The map is only the light-sampling pdf, which the estimate
        # divides by (kernel/light/background.h), so its size moves the noise, not the mean.
        w.cycles.sampling_method = 'MANUAL'
        detail = int(env.get("map_resolution", img.size[0]))
        w.cycles.sample_map_resolution = max(64, min(4096, detail))
    else:
        w.cycles.sampling_method = 'MANUAL'
        w.cycles.sample_map_resolution = 64
    bpy.context.scene.world = w
    return env


# ---------------------------------------------------------------- shader node expressions


class Expr:
    """Builds Math / Vector Math nodes in a node tree; operands are floats or sockets."""

    def __init__(self, nt):
        self.nt = nt

    def _in(self, sock, val):
        if isinstance(val, (int, float)):
            sock.default_value = float(val)
        else:
            self.nt.links.new(val, sock)

    def op(self, operation, a, b=0.0):
        n = self.nt.nodes.new('ShaderNodeMath')
        n.operation = operation
        n.use_clamp = False
        self._in(n.inputs[0], a)
        self._in(n.inputs[1], b)
        return n.outputs[0]

    def add(self, a, b):
        return self.op('ADD', a, b)

    def sub(self, a, b):
        return self.op('SUBTRACT', a, b)

    def mul(self, a, b):
        return self.op('MULTIPLY', a, b)

    def div(self, a, b):
        return self.op('DIVIDE', a, b)

    def pow(self, a, b):
        return self.op('POWER', a, b)

    def max(self, a, b):
        return self.op('MAXIMUM', a, b)

    def min(self, a, b):
        return self.op('MINIMUM', a, b)

    def sqrt(self, a):
        return self.op('SQRT', a)

    def geometry(self):
        if not hasattr(self, "_geo"):
            self._geo = self.nt.nodes.new('ShaderNodeNewGeometry')
        return self._geo

    def cos_nv(self):
        """(N.V)+ with N the shading normal (Cycles flips it to the viewer's side) and
        V = Geometry 'Incoming', the unit direction back along the incoming ray."""
        if not hasattr(self, "_nv"):
            g = self.geometry()
            d = self.nt.nodes.new('ShaderNodeVectorMath')
            d.operation = 'DOT_PRODUCT'
            self.nt.links.new(g.outputs['Normal'], d.inputs[0])
            self.nt.links.new(g.outputs['Incoming'], d.inputs[1])
            self._nv = self.min(self.max(d.outputs['Value'], 0.0), 1.0)
        return self._nv

    def cos_n_dir(self, direction):
        """(N.D)+ for a constant Blender-frame unit direction D."""
        g = self.geometry()
        d = self.nt.nodes.new('ShaderNodeVectorMath')
        d.operation = 'DOT_PRODUCT'
        self.nt.links.new(g.outputs['Normal'], d.inputs[0])
        d.inputs[1].default_value = direction
        return self.min(self.max(d.outputs['Value'], 0.0), 1.0)

    def rgb(self, r, g, b):
        n = self.nt.nodes.new('ShaderNodeCombineColor')
        n.mode = 'RGB'
        self._in(n.inputs[0], r)
        self._in(n.inputs[1], g)
        self._in(n.inputs[2], b)
        return n.outputs[0]

    def fresnel_dielectric(self, c, n):
        """Exact unpolarised Fresnel reflectance, cos c of the incident angle, relative index n
        (total internal reflection gives 1)."""
        g2 = self.add(self.sub(n * n, 1.0), self.mul(c, c))
        g = self.sqrt(self.max(g2, 0.0))
        a = self.sub(g, c)
        b = self.add(g, c)
        t1 = self.div(self.mul(a, a), self.max(self.mul(b, b), 1e-30))
        num = self.sub(self.mul(c, b), 1.0)
        den = self.add(self.mul(c, a), 1.0)
        t2 = self.add(1.0, self.div(self.mul(num, num), self.max(self.mul(den, den), 1e-30)))
        f = self.mul(self.mul(0.5, t1), t2)
        # g2 < 0 is total internal reflection: then F = 1 (reachable only for n < 1).
        tir = self.op('LESS_THAN', g2, 0.0)
        return self.add(self.mul(f, self.sub(1.0, tir)), tir)

    def fresnel_conductor(self, c, eta, k):
        """Exact unpolarised conductor Fresnel for complex index eta + ik (one channel)."""
        c2 = self.mul(c, c)
        s2 = self.sub(1.0, c2)
        t0 = self.sub(eta * eta - k * k, s2)
        a2b2 = self.sqrt(self.add(self.mul(t0, t0), 4.0 * eta * eta * k * k))
        a = self.sqrt(self.max(self.mul(self.add(a2b2, t0), 0.5), 0.0))
        t1 = self.add(a2b2, c2)
        t2 = self.mul(self.mul(a, c), 2.0)
        rs = self.div(self.sub(t1, t2), self.add(t1, t2))
        t3 = self.add(self.mul(c2, a2b2), self.mul(s2, s2))
        t4 = self.mul(t2, s2)
        rp = self.mul(rs, self.div(self.sub(t3, t4), self.add(t3, t4)))
        return self.mul(self.add(rs, rp), 0.5)


def build_material(i, spec, env):
    where = "materials[%d]" % i
    mat = bpy.data.materials.new(spec.get("name", "reflcheck_material_%d" % i))
    mat.use_nodes = True
    # Emitters must not become lights: nothing in the contract is lit by an emissive surface.
    mat.cycles.sample_as_light = False
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    out.target = 'CYCLES'
    e = Expr(nt)
    shaders = []

    def colour_times(base, factor):
        """base (list of 3 floats) times a scalar socket, or per-channel sockets."""
        if factor is None:
            return (base[0], base[1], base[2], 1.0)
        if isinstance(factor, list):
            return e.rgb(*(e.mul(factor[c], base[c]) for c in range(3)))
        return e.rgb(*(e.mul(factor, base[c]) for c in range(3)))

    def set_colour(sock, val):
        if isinstance(val, tuple):
            sock.default_value = val
        else:
            nt.links.new(val, sock)

    def textured(val, path):
        """val (a colour tuple or socket) times the texture at path: an Image Texture on the
        mesh's UVs, bilinear ('Linear'), repeat, the texels as written (linear float EXR)."""
        if path is None:
            return val
        tex = nt.nodes.new('ShaderNodeTexImage')
        tex.image = bpy.data.images.load(path, check_existing=True)
        tex.image.colorspace_settings.name = 'Linear'
        tex.image.alpha_mode = 'NONE'
        tex.interpolation = 'Linear'
        tex.extension = 'REPEAT'
        uv = nt.nodes.new('ShaderNodeUVMap')
        uv.uv_map = "UVMap"
        nt.links.new(uv.outputs['UV'], tex.inputs['Vector'])
        mix = nt.nodes.new('ShaderNodeMixRGB')
        mix.blend_type = 'MULTIPLY'
        mix.use_clamp = False
        mix.inputs['Fac'].default_value = 1.0
        set_colour(mix.inputs['Color1'], val)
        nt.links.new(tex.outputs['Color'], mix.inputs['Color2'])
        return mix.outputs['Color']

    def fresnel_factor(fr, at):
        """None (no factor), or one socket, or three sockets (per channel) of N.V."""
        if fr is None or fr["kind"] == "one":
            return None
        if fr["kind"] == "dielectric":
            return e.fresnel_dielectric(e.cos_nv(), float(fr["ior"]))
        if fr["kind"] == "conductor":
            return [e.fresnel_conductor(e.cos_nv(), fr["eta"][c], fr["k"][c]) for c in range(3)]
        if fr["kind"] == "schlick":
            w = e.pow(e.sub(1.0, e.cos_nv()), 5.0)
            return [e.add(fr["f0"][c], e.mul(1.0 - fr["f0"][c], w)) for c in range(3)]
        raise JobError("%s.kind '%s' unknown; expected one, schlick, dielectric or conductor" % (at, fr["kind"]))

    d = spec.get("diffuse")
    if d is not None:
        factor = None
        if d.get("sun_angle") is not None:  # D3D9Client eq. (8): [1 - R0 - m (1 - cos sigma)^p]
            sa = d["sun_angle"]
            cs = e.cos_n_dir(to_blender(sa["to_sun"]))
            factor = e.sub(1.0 - sa["r0"], e.mul(sa["m"], e.pow(e.sub(1.0, cs), sa["p"])))
        if d.get("fresnel_ior") is not None:  # validate: the light the coating does not reflect
            t = e.sub(1.0, e.fresnel_dielectric(e.cos_nv(), float(d["fresnel_ior"])))
            factor = t if factor is None else e.mul(factor, t)
        n = nt.nodes.new('ShaderNodeBsdfDiffuse')
        n.inputs['Roughness'].default_value = 0.0
        colour = colour_times(need(d, "color", where + ".diffuse"), factor)
        if d.get("vertex_colour"):
            # D3D's diffuse from the vertex colours (the objects' "Col" attribute, point domain:
            # interpolated across each face); the translator sends it without a factor.
            if factor is not None:
                raise JobError("%s.diffuse: vertex_colour with a factor is not translated" % where)
            attr = nt.nodes.new('ShaderNodeAttribute')
            attr.attribute_name = "Col"
            colour = attr.outputs['Color']
        set_colour(n.inputs['Color'], textured(colour, d.get("texture")))
        if d.get("one_sided"):
            # D3D's normal as given (d3d.two_sided false): Cycles turns N toward the ray, so on a
            # back face the given normal's side is beyond the surface, where a Translucent BSDF
            # takes light with the same cosine; a Diffuse BSDF there would light the wrong side.
            back = nt.nodes.new('ShaderNodeBsdfTranslucent')
            set_colour(back.inputs['Color'], textured(colour, d.get("texture")))
            geo = nt.nodes.new('ShaderNodeNewGeometry')
            mix = nt.nodes.new('ShaderNodeMixShader')
            nt.links.new(geo.outputs['Backfacing'], mix.inputs['Fac'])
            nt.links.new(n.outputs[0], mix.inputs[1])
            nt.links.new(back.outputs[0], mix.inputs[2])
            n = mix
        shaders.append(n.outputs[0])

    g = spec.get("glossy")
    if g is not None:
        n = nt.nodes.new('ShaderNodeBsdfGlossy')
        rough = float(need(g, "roughness", where + ".glossy"))
        # Roughness 0 is a perfect mirror: SHARP, which Beckmann cannot reach (alpha > 0). GGX
        # (a validate of a material with distribution ggx): alpha = Roughness^2 too.
        rough_dist = 'GGX' if g.get("distribution") == "ggx" else 'BECKMANN'
        n.distribution = 'SHARP' if rough == 0.0 else rough_dist
        n.inputs['Roughness'].default_value = rough
        factor = fresnel_factor(g.get("fresnel"), where + ".glossy.fresnel")
        set_colour(
            n.inputs['Color'], textured(colour_times(need(g, "color", where + ".glossy"), factor), g.get("texture"))
        )
        shaders.append(n.outputs[0])

    gl = spec.get("glass")
    if gl is not None:  # validate, a thin sheet: the slab's faces (setup_objects) in sharp glass
        n = nt.nodes.new('ShaderNodeBsdfGlass')
        n.distribution = 'SHARP'
        n.inputs['Color'].default_value = (1.0, 1.0, 1.0, 1.0)
        n.inputs['IOR'].default_value = float(need(gl, "ior", where + ".glass"))
        shaders.append(n.outputs[0])

    m = spec.get("mirror")
    if m is not None:
        if m["kind"] == "d3d9client":  # eq. (5): lambda + (s - lambda) R, R = R0 + m (1 - N.V)^p
            lam, s_col = need(m, "lambda", where + ".mirror"), need(m, "s", where + ".mirror")
            r = e.add(m["r0"], e.mul(m["m"], e.pow(e.sub(1.0, e.cos_nv()), m["p"])))
            col = e.rgb(*(e.add(lam[c], e.mul(s_col[c] - lam[c], r)) for c in range(3)))
        else:
            col = colour_times([1.0, 1.0, 1.0], fresnel_factor(m, where + ".mirror"))
        n = nt.nodes.new('ShaderNodeBsdfGlossy')
        n.distribution = 'SHARP'
        n.inputs['Roughness'].default_value = 0.0
        set_colour(n.inputs['Color'], col)
        shaders.append(n.outputs[0])

    em = spec.get("emission")
    if em is not None:
        n = nt.nodes.new('ShaderNodeEmission')
        set_colour(n.inputs['Color'], textured((em[0], em[1], em[2], 1.0), spec.get("emission_texture")))
        n.inputs['Strength'].default_value = 1.0
        shaders.append(n.outputs[0])

    if not shaders:
        # Black diffuse, not a holdout: a holdout would cut the coverage.
        n = nt.nodes.new('ShaderNodeBsdfDiffuse')
        n.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
        shaders.append(n.outputs[0])
    acc = shaders[0]
    for sh in shaders[1:]:
        a = nt.nodes.new('ShaderNodeAddShader')
        nt.links.new(acc, a.inputs[0])
        nt.links.new(sh, a.inputs[1])
        acc = a.outputs[0]
    bl = spec.get("blend")
    if bl is not None:
        # D3D's SRCALPHA/INVSRCALPHA blend: c a + behind (1 - a) is a Mix of a Transparent BSDF
        # (weight 1 - a, the path goes on straight) and the surface (weight a).
        mix = nt.nodes.new('ShaderNodeMixShader')
        a = blend_alpha(nt, e, bl, m, env, where)
        if isinstance(a, float):
            mix.inputs['Fac'].default_value = a
        else:
            nt.links.new(a, mix.inputs['Fac'])
        nt.links.new(nt.nodes.new('ShaderNodeBsdfTransparent').outputs[0], mix.inputs[1])
        nt.links.new(acc, mix.inputs[2])
        acc = mix.outputs[0]
    nt.links.new(acc, out.inputs['Surface'])
    return mat


def blend_alpha(nt, e, bl, mirror, env, where):
    """D3D9Client eq. (7), a = max(d_a, |R_tot|) clamped to [0, 1] as the blend unit takes it:
    R_tot = (lambda + (s - lambda) R) phi (eq. 5), phi the environment along the mirror direction
    (Texture Coordinate Reflection: 2 (N.I) N - I in world space, the direction the world shader
    looks the image up along), |.| = w_max max + w . c + w_euclid |c|_2 (d3d9client_norm_weights)."""
    d_a = float(need(bl, "d_a", where + ".blend"))
    kind = env.get("type", "none")
    if mirror is None or kind == "none":
        return min(max(d_a, 0.0), 1.0)  # no environment: R_tot = 0
    lam, s_col = need(mirror, "lambda", where + ".mirror"), need(mirror, "s", where + ".mirror")
    r = e.add(mirror["r0"], e.mul(mirror["m"], e.pow(e.sub(1.0, e.cos_nv()), mirror["p"])))
    if kind == "constant":
        phi = list(need(env, "radiance", "environment"))
    else:
        tc = nt.nodes.new('ShaderNodeTexCoord')
        tex = nt.nodes.new('ShaderNodeTexEnvironment')
        tex.image = bpy.data.images.load(need(env, "path", "environment"), check_existing=True)
        tex.image.colorspace_settings.name = 'Linear'
        tex.interpolation = 'Linear'
        tex.projection = 'EQUIRECTANGULAR'
        nt.links.new(tc.outputs['Reflection'], tex.inputs['Vector'])
        sep = nt.nodes.new('ShaderNodeSeparateColor')
        nt.links.new(tex.outputs['Color'], sep.inputs['Color'])
        scale = need(env, "scale", "environment")
        phi = [e.mul(sep.outputs[c], float(scale[c])) for c in range(3)]
    rt = [e.mul(e.add(lam[c], e.mul(s_col[c] - lam[c], r)), phi[c]) for c in range(3)]
    norm = e.mul(float(bl["w_max"]), e.max(rt[0], e.max(rt[1], rt[2])))
    for c, k in enumerate(("w_r", "w_g", "w_b")):
        norm = e.add(norm, e.mul(float(bl[k]), rt[c]))
    euclid = e.sqrt(e.add(e.mul(rt[0], rt[0]), e.add(e.mul(rt[1], rt[1]), e.mul(rt[2], rt[2]))))
    norm = e.add(norm, e.mul(float(bl["w_euclid"]), euclid))
    return e.min(e.max(e.max(d_a, norm), 0.0), 1.0)


def setup_objects(job, materials):
    for i, o in enumerate(need(job, "objects", "job")):
        where = "objects[%d]" % i
        v = need(o, "verts", where)
        nrm = need(o, "normals", where)
        t = need(o, "tris", where)
        if len(v) % 3 or len(nrm) != len(v) or len(t) % 3:
            raise JobError("%s: verts, normals and tris must hold whole triples of equal count" % where)
        verts = [tuple(to_blender(v[j : j + 3])) for j in range(0, len(v), 3)]
        normals = [tuple(to_blender(nrm[j : j + 3]).normalized()) for j in range(0, len(nrm), 3)]
        faces = [tuple(t[j : j + 3]) for j in range(0, len(t), 3)]
        thin = o.get("thin")
        if thin is not None:
            # A thin sheet: the surface and a copy `thin` behind it along the normal, facing the
            # other way, so that light crosses two faces; no rim (a ray leaves through the copy).
            k = len(verts)
            verts += [tuple(p[c] - thin * q[c] for c in range(3)) for p, q in zip(verts, normals)]
            normals += [tuple(-q[c] for c in range(3)) for q in normals]
            faces += [(a + k, c + k, b + k) for a, b, c in faces]
            if o.get("uvs") is not None:
                o["uvs"] = o["uvs"] + o["uvs"]
        me = bpy.data.meshes.new("reflcheck_mesh_%d" % i)
        me.from_pydata(verts, [], faces)
        me.polygons.foreach_set("use_smooth", [True] * len(me.polygons))
        me.use_auto_smooth = True
        me.auto_smooth_angle = math.pi
        me.normals_split_custom_set_from_vertices(normals)
        # The same normals unquantised: Blender stores custom split normals as two 16-bit
        # angles (and one within 1e-4 of its own vertex normal as that normal), 1.6e-4 rad off
        # in the median; exact_normals feeds the closures this float copy (docs/conventions.md).
        at = me.attributes.new(EXACT_NORMAL, 'FLOAT_VECTOR', 'POINT')
        at.data.foreach_set("vector", [c for q in normals for c in q])
        uvs = o.get("uvs")
        if uvs is not None:
            if len(uvs) != 2 * len(verts):
                raise JobError("%s: uvs must hold one (u, v) pair per vertex" % where)
            layer = me.uv_layers.new(name="UVMap")
            vi = [0] * len(me.loops)
            me.loops.foreach_get("vertex_index", vi)
            flat = []
            for k in vi:
                flat += (uvs[2 * k], uvs[2 * k + 1])
            layer.data.foreach_set("uv", flat)
        colours = o.get("colours")
        if colours is not None:
            if len(colours) != len(v):
                raise JobError("%s: colours must hold one (r, g, b) per vertex" % where)
            attr = me.color_attributes.new(name="Col", type='FLOAT_COLOR', domain='POINT')
            flat = []
            for k in range(len(verts)):
                flat += (colours[3 * k], colours[3 * k + 1], colours[3 * k + 2], 1.0)
            attr.data.foreach_set("color", flat)
        mi = int(need(o, "material", where))
        if mi < 0 or mi >= len(materials):
            raise JobError("%s: material %d out of range" % (where, mi))
        me.materials.append(materials[mi])
        ob = bpy.data.objects.new(o.get("name", "reflcheck_object_%d" % i), me)
        ob.pass_index = int(need(o, "pass_index", where))
        # The real-time models have no shadows and no inter-reflection (harness/CONTRACT.md);
        # a validate has them when its physics asks.
        physics = need(job, "physics", "job")
        inter = bool(need(physics, "interreflection", "physics"))
        ob.visible_camera = True
        ob.visible_shadow = bool(need(physics, "shadows", "physics"))
        ob.visible_glossy = inter or thin is not None  # a sheet's internal reflections
        ob.visible_diffuse = inter
        # Seen through a thin sheet: what lies behind it is reached by transmission rays.
        ob.visible_transmission = any(x.get("thin") is not None for x in job["objects"])
        ob.visible_volume_scatter = False
        bpy.context.scene.collection.objects.link(ob)


# ---------------------------------------------------------------- passes and output


def exact_normals(mat):
    """Points every closure's Normal and every Geometry 'Normal' of mat at the float copy of
    the vertex normals (setup_objects), interpolated over the triangle as Cycles interpolates
    its own (triangle_smooth_normal) and turned to the viewer's side as Cycles turns sd->N on
    a back face: normalize(n) (1 - 2 Backfacing)."""
    nt = mat.node_tree
    a = nt.nodes.new('ShaderNodeAttribute')
    a.attribute_type = 'GEOMETRY'
    a.attribute_name = EXACT_NORMAL
    unit = nt.nodes.new('ShaderNodeVectorMath')
    unit.operation = 'NORMALIZE'
    nt.links.new(a.outputs['Vector'], unit.inputs[0])
    side = nt.nodes.new('ShaderNodeMath')
    side.operation = 'MULTIPLY_ADD'
    nt.links.new(nt.nodes.new('ShaderNodeNewGeometry').outputs['Backfacing'], side.inputs[0])
    side.inputs[1].default_value = -2.0
    side.inputs[2].default_value = 1.0
    n = nt.nodes.new('ShaderNodeVectorMath')
    n.operation = 'SCALE'
    nt.links.new(unit.outputs['Vector'], n.inputs[0])
    nt.links.new(side.outputs['Value'], n.inputs['Scale'])
    for node in list(nt.nodes):
        normal = node.inputs.get('Normal') if node.bl_idname.startswith('ShaderNodeBsdf') else None
        if normal is not None and not normal.is_linked:
            nt.links.new(n.outputs['Vector'], normal)
    for link in list(nt.links):
        if link.from_node.bl_idname == 'ShaderNodeNewGeometry' and link.from_socket.name == 'Normal':
            nt.links.new(n.outputs['Vector'], link.to_socket)


def compositor(sc, vl):
    """The scene's compositor emptied down to a Render Layers node of view layer vl. Returns the
    node tree, that node's outputs, and mix(kind, a, b): a MixRGB node of blend kind (factor 1,
    unclamped, so radiance above 1 passes) on a and b, each a socket or an RGBA tuple."""
    sc.use_nodes = True
    nt = sc.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    rl = nt.nodes.new('CompositorNodeRLayers')
    rl.layer = vl.name

    def mix(kind, a, b):
        n = nt.nodes.new('CompositorNodeMixRGB')
        n.blend_type = kind
        n.use_clamp = False
        n.use_alpha = False
        n.inputs[0].default_value = 1.0
        for sock, val in ((n.inputs[1], a), (n.inputs[2], b)):
            if isinstance(val, tuple):
                sock.default_value = val
            else:
                nt.links.new(val, sock)
        return n.outputs[0]

    return nt, rl.outputs, mix


def setup_compositor(job, base_path):
    sc = bpy.context.scene
    vl = sc.view_layers[0]
    vl.use_pass_combined = True
    vl.use_pass_z = False
    vl.use_pass_diffuse_direct = True
    vl.use_pass_diffuse_indirect = True
    vl.use_pass_diffuse_color = True
    vl.use_pass_glossy_direct = True
    vl.use_pass_glossy_indirect = True
    vl.use_pass_glossy_color = True
    vl.use_pass_emit = True
    vl.use_pass_environment = True
    vl.use_pass_object_index = True
    nt, o, mix = compositor(sc, vl)
    diffuse = mix('MULTIPLY', mix('ADD', o['DiffDir'], o['DiffInd']), o['DiffCol'])
    glossy = mix('MULTIPLY', mix('ADD', o['GlossDir'], o['GlossInd']), o['GlossCol'])
    specular, reflection = route_glossy(job, mix, glossy)
    obj = nt.nodes.new('CompositorNodeMath')
    obj.operation = 'SUBTRACT'
    obj.use_clamp = False
    nt.links.new(o['IndexOB'], obj.inputs[0])
    obj.inputs[1].default_value = 1.0
    terms = [("diffuse", diffuse), ("specular", specular), ("reflection", reflection), ("emission", o['Emit'])]
    return write_layers(nt, o, mix, base_path, terms, [("object", obj.outputs[0])])


def route_glossy(job, mix, glossy):
    """The glossy pass as (specular, reflection) under the job's glossy_aov: the named one gets
    it, the other black."""
    black = (0.0, 0.0, 0.0, 1.0)
    route = need(job, "glossy_aov", "job")
    if route not in ("specular", "reflection"):
        raise JobError("glossy_aov '%s' unknown; expected specular or reflection" % route)
    return (
        glossy if route == "specular" else mix('MULTIPLY', glossy, black),
        glossy if route == "reflection" else mix('MULTIPLY', glossy, black),
    )


def write_layers(nt, o, mix, base_path, terms, extra):
    """One 32-bit uncompressed multilayer EXR at base_path: the beauty (Image plus the background, alpha the
    coverage), the term layers, background and coverage, then the extra layers. Returns the
    File Output node; the Composite node it adds is what makes the compositor run in background
    mode."""
    seta = nt.nodes.new('CompositorNodeSetAlpha')
    seta.mode = 'REPLACE_ALPHA'
    nt.links.new(mix('ADD', o['Image'], o['Env']), seta.inputs['Image'])
    nt.links.new(o['Alpha'], seta.inputs['Alpha'])
    fo = nt.nodes.new('CompositorNodeOutputFile')
    fo.base_path = base_path
    f = fo.format
    f.file_format = 'OPEN_EXR_MULTILAYER'
    f.color_depth = '32'
    # Uncompressed: the file lives until reflcheck has read it (cycles_collect, eevee_collect),
    # and ZIP's compression here and decompression there cost 1.3 CPU-s of a 5.7 CPU-s full-size
    # twin (lambert_calibration) for the same floats.
    f.exr_codec = 'NONE'
    fo.layer_slots.clear()
    layers = [("", seta.outputs[0])] + terms + [("background", o['Env']), ("coverage", o['Alpha'])] + extra
    for name, src in layers:
        fo.layer_slots.new(name)
        nt.links.new(src, fo.inputs[len(fo.inputs) - 1])
    comp = nt.nodes.new('CompositorNodeComposite')
    nt.links.new(seta.outputs[0], comp.inputs['Image'])
    return fo


def render_job(job_path, out_path, threads=None):
    """One job: the whole scene is rebuilt from factory settings, so a process may render many
    jobs in turn (worker.py) with the same result as one Blender per job. threads: None keeps
    Blender's setting (its -t option), 0 all cores, N > 0 exactly N."""
    t0 = time.monotonic()
    try:
        with open(job_path) as fh:
            job = json.load(fh)
    except (OSError, ValueError) as e:
        raise JobError("%s: cannot read the job: %s; rewrite it with reflcheck cycles-job" % (job_path, e))
    if job.get("format") != "reflcheck-cycles-job" or job.get("version") != 1:
        raise JobError("%s: not a version 1 reflcheck Cycles job" % job_path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    setup_render(job)
    if threads is not None:
        r = bpy.context.scene.render
        r.threads_mode = 'FIXED' if threads > 0 else 'AUTO'
        if threads > 0:
            r.threads = threads
    setup_camera(job)
    setup_lights(job)
    env = setup_world(job)
    mats = [build_material(i, m, env) for i, m in enumerate(need(job, "materials", "job"))]
    if any(o.get("thin") is not None for o in job["objects"]):
        # A thin sheet (validate): a camera ray crosses two faces, and every internal reflection
        # is one more; 16 leave the sum's remainder R^16 < 1e-17 for glass. The diffuse keeps the
        # physics' bounces: what is behind the sheet is lit directly.
        cy = bpy.context.scene.cycles
        cy.max_bounces = max(cy.max_bounces, 16)
        cy.glossy_bounces = max(cy.glossy_bounces, 16)
        cy.transmission_bounces = 16
        # The light a sheet reflects between its faces leaves it as a transmission ray: the world
        # must be visible to those, as it is to the first face's glossy reflection.
        bpy.context.scene.world.cycles_visibility.transmission = True
    if any(m.get("blend") is not None for m in job["materials"]):
        # A blended surface passes the path on through a Transparent BSDF: one transparent bounce
        # per blended surface along a camera ray (render.h draws each blended object once).
        bpy.context.scene.cycles.transparent_max_bounces = 64
    setup_objects(job, mats)
    for m in mats:
        exact_normals(m)
    stem = out_path[:-4] if out_path.lower().endswith(".exr") else out_path
    tmp_base = "%s.tmp%d_" % (stem, os.getpid())
    fo = setup_compositor(job, tmp_base)
    t_build = time.monotonic() - t0
    seeds = need(job, "seeds", "job")
    if not seeds:
        raise JobError("job: seeds is empty")
    render_s = []
    # Only the seed changes between the seeds' renders: persistent data keeps Cycles' session
    # (the environment image loaded, the world's importance map, the BVH, the compiled shaders)
    # from one to the next, each seed's image bit-identical to a fresh Blender's
    # (tests/cycles_setup.sh). A seed set from Python does not tag the scene, and the kept
    # session would render the old seed again: update_tag makes it re-read the integrator.
    # Loading the factory settings (the next job in a worker) frees the kept session.
    sc = bpy.context.scene
    sc.render.use_persistent_data = len(seeds) > 1
    for i, seed in enumerate(seeds):
        sc.cycles.seed = int(seed)
        sc.update_tag()
        t1 = time.monotonic()
        bpy.ops.render.render(write_still=False)
        render_s.append(time.monotonic() - t1)
        written = tmp_base + "%04d.exr" % bpy.context.scene.frame_current
        if not os.path.isfile(written):
            raise JobError("the compositor wrote no file %s; check disk space and permissions" % written)
        os.replace(written, "%s.cyc%d.exr" % (stem, i))
    wc = bpy.context.scene.world.cycles
    world_map = wc.sample_map_resolution if wc.sampling_method == 'MANUAL' else 0
    timing = {
        "blender": bpy.app.version_string,
        "build_s": t_build,
        "render_s": render_s,
        "samples": job["samples"],
        "seeds": seeds,
        "threads": bpy.context.scene.render.threads,
        "world_map": world_map,
    }
    with open(stem + ".timing.json", "w") as fh:
        json.dump(timing, fh)
    print(
        "reflcheck-cycles: build %.3f s, render %s s, world map %d"
        % (t_build, " ".join("%.3f" % r for r in render_s), world_map)
    )


def main():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    if len(argv) != 2:
        raise JobError("usage: blender -b --factory-startup -P cycles_render.py -- JOB.json OUT.exr")
    render_job(argv[0], argv[1])


if __name__ == "__main__":
    try:
        main()
    except JobError as e:
        print("cycles_render.py: error: %s" % e, file=sys.stderr)
        sys.stderr.flush()
        sys.exit(1)
    except Exception:
        traceback.print_exc()
        print("cycles_render.py: error: unexpected failure (traceback above)", file=sys.stderr)
        sys.stderr.flush()
        sys.exit(1)
