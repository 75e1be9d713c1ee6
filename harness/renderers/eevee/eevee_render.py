"""eevee_render.py - render a reflcheck Cycles job (harness/renderers/cycles/cycles.c) in EEVEE.

Usage (an OpenGL context is needed: headless, under Xvfb with Mesa's llvmpipe):
    xvfb-run -a blender -b --factory-startup --python-exit-code 1 \
        -P harness/renderers/eevee/eevee_render.py -- JOB.json OUT.exr

The scene translation is Cycles' own (cycles_render.py, imported from beside this folder):
camera, lights, world, material node trees and meshes are built by the same functions, so
EEVEE and Cycles render one Blender scene and differ only in the engine. What is EEVEE's:
  - the light units: EEVEE draws a point or spot as a sphere light and a sun as a disc, each
    normalised to Cycles' power for its radius (eevee_lights.c, light_shape_power_get);
    Blender clamps a zero radius to 0.001, whose relative error at 1 m is 1e-6;
  - the settings below, fixed (EEVEE_SETTINGS, also written to the timing file);
  - the passes: EEVEE has Diffuse Light and Specular Light (direct and indirect in one) and
    their colours, Emission, Environment and shader AOVs; no object index.

It writes OUT.eevee.exr (32-bit float multilayer, uncompressed) with the channels
    R G B A              Combined + Environment; A = alpha (coverage)
    diffuse.RGBA         Diffuse Light * Diffuse Colour
    specular.RGBA        Specular Light * Specular Colour when the job routes glossy there
    reflection.RGBA      the same when routed to "reflection"
    emission.RGBA        Emission
    background.RGBA      Environment (the world seen by camera rays)
    coverage.V           Alpha
(a term's layer that no material can light is 0, and its passes are not drawn: job_terms),
and OUT.timing.json (build and render seconds, the passes asked, the settings).
harness/renderers/eevee/eevee.c renames the channels. Any failure prints "eevee_render.py: error: ..."
and exits with 1.
"""

import json
import os
import sys
import time
import traceback

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "cycles"))
import cycles_render as cr  # noqa: E402  (the shared Blender scene translation)

# Fixed EEVEE settings (docs/eevee.md). Samples come from the job (the scene's samples).
EEVEE_SETTINGS = {
    # A light's influence ends where its intensity falls below this; 1e-6 puts that beyond
    # 100 m for every canonical light (their intensities are >= 1e-2 W/sr), where 0.01, the
    # default, would cut a 1 W/sr light at 10 m.
    "light_threshold": 1e-6,
    "use_soft_shadows": False,
    "use_ssr": False,
    "use_gtao": False,
    "use_bloom": False,
    "use_motion_blur": False,
    "use_volumetric_lights": False,
    "use_taa_reprojection": False,
    # Reflection cubemap of the world: the largest size, no glossy clamp.
    "gi_cubemap_resolution": "512",
    "gi_glossy_clamp": 0.0,
    "gi_filter_quality": 0.25,
    "gi_diffuse_bounces": 0,
    "use_overscan": False,
    "use_shadow_high_bitdepth": True,
    # EEVEE jitters TAA samples by a Blackman-Harris distribution over +-2 filter_size pixels
    # (eevee_temporal_sampling.c); its deviation is 0.554 filter_size, and 0.52 gives the
    # 0.289 px of the rasterizer's one-pixel box.
    "filter_size": 0.52,
}


def setup_eevee(job):
    """EEVEE on top of cycles_render.setup_render (size, film, colour management)."""
    cr.setup_render(job)
    sc = bpy.context.scene
    sc.render.engine = 'BLENDER_EEVEE'
    ee = sc.eevee
    ee.taa_render_samples = int(cr.need(job, "samples", "job"))
    for k, v in EEVEE_SETTINGS.items():
        if k == "filter_size":
            sc.render.filter_size = v
        else:
            setattr(ee, k, v)
    # Standard view transform, no look, exposure 0, gamma 1 (set by setup_render); the EXR is
    # written linear by the compositor's file output whatever the view transform says.
    sc.display_settings.display_device = 'sRGB'


def setup_eevee_lights():
    """No shadow of any kind (the real-time models have none). Which closures a lamp lights
    (the physics manifest) Cycles reads from the lamp's ray visibility, which
    cycles_render.setup_lights sets; EEVEE reads its diffuse and specular factors."""
    for ob in bpy.context.scene.objects:
        if ob.type != 'LIGHT':
            continue
        ob.data.use_shadow = False
        ob.data.use_contact_shadow = False
        ob.data.use_custom_distance = False
        ob.data.diffuse_factor = 1.0 if ob.visible_diffuse else 0.0
        ob.data.specular_factor = 1.0 if ob.visible_glossy else 0.0


def setup_eevee_materials():
    for m in bpy.data.materials:
        m.shadow_method = 'NONE'
        m.blend_method = 'OPAQUE'
        m.use_screen_refraction = False
        if m.node_tree is not None:
            for n in m.node_tree.nodes:
                if n.bl_idname == 'ShaderNodeOutputMaterial':
                    n.target = 'ALL'


# The closure keys of a job's material (cycles_render.build_material) and the passes EEVEE fills
# from them: a Diffuse BSDF the diffuse light and colour, a Glossy BSDF (a lobe or a mirror) the
# specular ones, an Emission the emission. Glass and a blend (a Transparent BSDF mixed in) are
# not sorted out: a job with one asks every pass, as does a material with no closure (drawn as
# a black Diffuse BSDF).
CLOSURE_PASSES = {"diffuse": "diffuse", "glossy": "glossy", "mirror": "glossy", "emission": "emission"}
UNSORTED_CLOSURES = ("glass", "blend")


def job_terms(job):
    """The terms ("diffuse", "glossy", "emission") some material of the job can put light in."""
    terms = set()
    for m in cr.need(job, "materials", "job"):
        keys = [k for k in m if m[k] is not None]
        if any(k in UNSORTED_CLOSURES for k in keys) or not any(k in CLOSURE_PASSES for k in keys):
            return {"diffuse", "glossy", "emission"}
        terms.update(CLOSURE_PASSES[k] for k in keys if k in CLOSURE_PASSES)
    return terms


def setup_compositor(job, base_path):
    """The passes and the layers. EEVEE draws every material once more per TAA sample for each
    material pass asked (Emission, Diffuse and Specular Light and Colour, each shader AOV:
    EEVEE_material_output_accumulate in eevee_materials.c), 0.06 CPU-s a pass per sample at
    256 x 192 on one llvmpipe thread: a pass is asked only where a layer needs it. No material
    writes a shader AOV (cycles_render.py builds none), so none is asked; a term no material
    has is 0 at every pixel in its passes, and its layer is written as that 0."""
    sc = bpy.context.scene
    vl = sc.view_layers[0]
    terms = job_terms(job)
    vl.use_pass_combined = True
    vl.use_pass_z = False
    vl.use_pass_diffuse_direct = vl.use_pass_diffuse_color = "diffuse" in terms
    vl.use_pass_glossy_direct = vl.use_pass_glossy_color = "glossy" in terms
    vl.use_pass_emit = "emission" in terms
    vl.use_pass_environment = True
    nt, o, mix = cr.compositor(sc, vl)
    # A zero layer is a pass times black, the way route_glossy blacks the unrouted layer (a
    # constant-only input has no size in the compositor); Alpha, in [0, 1], makes it 0 exactly
    # where a light pass could hold a half-float overflow (inf times 0 is NaN).
    zero = mix('MULTIPLY', o['Alpha'], (0.0, 0.0, 0.0, 1.0))
    diffuse = mix('MULTIPLY', o['DiffDir'], o['DiffCol']) if "diffuse" in terms else zero
    glossy = mix('MULTIPLY', o['GlossDir'], o['GlossCol']) if "glossy" in terms else zero
    specular, reflection = cr.route_glossy(job, mix, glossy)
    emission = o['Emit'] if "emission" in terms else zero
    layers = [("diffuse", diffuse), ("specular", specular), ("reflection", reflection), ("emission", emission)]
    return cr.write_layers(nt, o, mix, base_path, layers, [])


def asked_passes():
    """The passes the view layer asks of EEVEE (its use_pass_* flags, then "aov:NAME" for each
    shader AOV), for the timing file: each material pass is one more draw per TAA sample."""
    vl = bpy.context.scene.view_layers[0]
    flags = sorted(p.identifier for p in vl.bl_rna.properties if p.identifier.startswith("use_pass_"))
    return [f for f in flags if getattr(vl, f)] + ["aov:" + a.name for a in vl.aovs]


def gl_renderer():
    """The OpenGL renderer EEVEE drew with (here Mesa's llvmpipe), for the record."""
    try:
        import gpu

        return gpu.platform.renderer_get()
    except (ImportError, AttributeError, RuntimeError):
        return ""


def render_job(job_path, out_path, threads=0):
    """One job, from the factory settings on: what a fresh Blender running this script does
    (eevee_worker.py calls it job after job). threads is the worker protocol's; llvmpipe's own
    threads are fixed when the worker starts (LP_NUM_THREADS)."""
    t0 = time.monotonic()
    try:
        with open(job_path) as fh:
            job = json.load(fh)
    except (OSError, ValueError) as e:
        raise cr.JobError("%s: cannot read the job: %s; render it again" % (job_path, e))
    if job.get("format") != "reflcheck-cycles-job" or job.get("version") != 1:
        raise cr.JobError("%s: not a version 1 reflcheck Cycles job" % job_path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    setup_eevee(job)
    cr.setup_camera(job)
    cr.setup_lights(job)
    setup_eevee_lights()
    env = cr.setup_world(job)
    mats = [cr.build_material(i, m, env) for i, m in enumerate(cr.need(job, "materials", "job"))]
    cr.setup_objects(job, mats)
    setup_eevee_materials()
    stem = out_path[:-4] if out_path.lower().endswith(".exr") else out_path
    tmp_base = "%s.tmp%d_" % (stem, os.getpid())
    setup_compositor(job, tmp_base)
    t_build = time.monotonic() - t0
    t1 = time.monotonic()
    bpy.ops.render.render(write_still=False)
    render_s = time.monotonic() - t1
    written = tmp_base + "%04d.exr" % bpy.context.scene.frame_current
    if not os.path.isfile(written):
        raise cr.JobError("the compositor wrote no file %s; check disk space and permissions" % written)
    os.replace(written, stem + ".eevee.exr")
    timing = {
        "blender": bpy.app.version_string,
        "opengl": gl_renderer(),
        "build_s": t_build,
        "render_s": render_s,
        "samples": job["samples"],
        "passes": asked_passes(),
        "settings": EEVEE_SETTINGS,
    }
    with open(stem + ".timing.json", "w") as fh:
        json.dump(timing, fh)
    print("reflcheck-eevee: build %.3f s, render %.3f s, %s" % (t_build, render_s, timing["opengl"]))


def main():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    if len(argv) != 2:
        raise cr.JobError("usage: blender -b --factory-startup -P eevee_render.py -- JOB.json OUT.exr")
    render_job(*argv)


if __name__ == "__main__":
    try:
        main()
    except cr.JobError as e:
        print("eevee_render.py: error: %s" % e, file=sys.stderr)
        sys.stderr.flush()
        sys.exit(1)
    except Exception:
        traceback.print_exc()
        print("eevee_render.py: error: unexpected failure (traceback above)", file=sys.stderr)
        sys.stderr.flush()
        sys.exit(1)
