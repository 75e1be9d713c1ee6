/* bench_llvmpipe - the benchmark scene rendered by Mesa's llvmpipe through OSMesa, for a
 * side-by-side time and image comparison with reflcheck's rasterizer (tests/bench/README.md).
 *
 * Usage: bench_llvmpipe --scene FILE --size N --k K --tris T --threads N [--reps R]
 *                       [--prepass 0|1] [--out FILE]
 * Prints one JSON object on stdout (times in ms). --out writes the linear float R, G, B
 * image (bench image format, see bench_image.h) for the per-pixel difference.
 *
 * The same work as render_scene: the same mesh and camera (clip x = (d.right)/tan_x,
 * y = (d.up)/tan_y, w = d.forward), per-fragment D3D lighting (light colour E/pi, Blinn-Phong
 * with a local viewer) and the D3D9Client Fresnel environment term, the environment as an
 * equirectangular RGB32F texture with GL_LINEAR (texel centres at +0.5 like env_lookup),
 * REPEAT in u and CLAMP_TO_EDGE in v, the background where no triangle is. Supersampling
 * k x k is done as render_scene does it: the frame is rendered at k times the size into an
 * RGBA32F target and box-filtered down by a second pass (timed). --prepass 1 adds a depth-only
 * pass so that every sample is shaded once, as in the rasterizer (no overdraw).
 * LP_NUM_THREADS is set from --threads before the context exists.
 */
#define GL_GLEXT_PROTOTYPES 1
#include <GL/osmesa.h>
#include <GL/glext.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_image.h"
#include "bench_scene.h"
#include "render.h"

/* Shared by both shading programs: env_lookup's mapping (env.h). */
#define BENCH_GLSL_ENV                                                                                                 \
    "uniform sampler2D u_env;\n"                                                                                       \
    "uniform vec3 u_env_scale;\n"                                                                                      \
    "vec3 env(vec3 d) {\n"                                                                                             \
    "    d = normalize(d);\n"                                                                                          \
    "    float y = clamp(d.y, -1.0, 1.0);\n"                                                                           \
    "    float u = 0.5 + atan(d.z, d.x) / 6.28318530717958647692;\n"                                                   \
    "    float v = 0.5 + asin(y) / 3.14159265358979323846;\n"                                                          \
    "    return textureLod(u_env, vec2(u, 1.0 - v), 0.0).rgb * u_env_scale;\n"                                         \
    "}\n"

static const char *const bench_vs_mesh =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec3 a_nrm;\n"
    "uniform vec3 u_eye, u_right, u_up, u_fwd;\n"
    "uniform vec2 u_tan;\n"
    "uniform float u_near, u_far;\n"
    "out vec3 v_pos;\n"
    "out vec3 v_nrm;\n"
    "invariant gl_Position;\n"
    "void main() {\n"
    "    vec3 d = a_pos - u_eye;\n"
    "    float w = dot(d, u_fwd);\n"
    "    float z = (w * (u_far + u_near) - 2.0 * u_far * u_near) / (u_far - u_near);\n"
    "    gl_Position = vec4(dot(d, u_right) / u_tan.x, dot(d, u_up) / u_tan.y, z, w);\n"
    "    v_pos = a_pos;\n"
    "    v_nrm = a_nrm;\n"
    "}\n";

static const char *const bench_fs_depth = "#version 330 core\n"
                                          "void main() {}\n";

/* Lights: u_lpos.w = 0 for a sun (xyz = unit direction to the light), 1 for a point light
 * with 1/d^2 falloff; u_lint is I or E. */
static const char *const bench_fs_shade = "#version 330 core\n" BENCH_GLSL_ENV "in vec3 v_pos;\n"
                                          "in vec3 v_nrm;\n"
                                          "out vec4 o_rgba;\n"
                                          "uniform vec3 u_eye;\n"
                                          "uniform int u_nlights;\n"
                                          "uniform vec4 u_lpos[8];\n"
                                          "uniform vec3 u_lint[8];\n"
                                          "uniform vec3 u_vd, u_vs, u_ve, u_lambda, u_fcol;\n"
                                          "uniform float u_power, u_r0, u_m, u_fp, u_dw;\n"
                                          "void main() {\n"
                                          "    vec3 n = normalize(v_nrm);\n"
                                          "    vec3 v = normalize(u_eye - v_pos);\n"
                                          "    if (dot(n, v) < 0.0) n = -n;\n"
                                          "    vec3 diff = vec3(0.0), spec = vec3(0.0);\n"
                                          "    for (int i = 0; i < u_nlights; i++) {\n"
                                          "        vec3 l, e;\n"
                                          "        if (u_lpos[i].w == 0.0) { l = u_lpos[i].xyz; e = u_lint[i]; }\n"
                                          "        else { vec3 d = u_lpos[i].xyz - v_pos; float dist = length(d); l = "
                                          "d / dist; e = u_lint[i] / (dist * dist); }\n"
                                          "        float nl = dot(n, l);\n"
                                          "        if (nl <= 0.0) continue;\n"
                                          "        vec3 c = e * 0.318309886183790671538;\n"
                                          "        diff += u_vd * c * min(nl, 1.0);\n"
                                          "        float nh = dot(n, normalize(l + v));\n"
                                          "        spec += u_vs * c * (nh > 0.0 ? pow(min(nh, 1.0), u_power) : 0.0);\n"
                                          "    }\n"
                                          "    float r = u_r0 + u_m * pow(1.0 - clamp(dot(n, v), 0.0, 1.0), u_fp);\n"
                                          "    vec3 refl = (u_lambda * (1.0 - r) + u_fcol * r) * env(reflect(-v, n));\n"
                                          "    o_rgba = vec4(diff * u_dw + spec + refl + u_ve, 1.0);\n"
                                          "}\n";

/* A triangle covering the screen at depth 1 (z = w): drawn after the mesh with GL_LEQUAL,
 * so only samples no triangle covers run it. */
static const char *const bench_vs_full =
    "#version 330 core\n"
    "void main() {\n"
    "    vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);\n"
    "    gl_Position = vec4(p, 1.0, 1.0);\n"
    "}\n";

static const char *const bench_fs_background = "#version 330 core\n" BENCH_GLSL_ENV "out vec4 o_rgba;\n"
                                               "uniform vec3 u_right, u_up, u_fwd;\n"
                                               "uniform vec2 u_tan;\n"
                                               "uniform vec2 u_size;\n" /* final image size in pixels */
                                               "uniform float u_k;\n"
                                               "void main() {\n"
                                               "    float sx = gl_FragCoord.x / u_k;\n"
                                               "    float sy = (u_size.y * u_k - gl_FragCoord.y) / u_k;\n"
                                               "    float nx = 2.0 * sx / u_size.x - 1.0;\n"
                                               "    float ny = 1.0 - 2.0 * sy / u_size.y;\n"
                                               "    vec3 d = u_fwd + u_right * (nx * u_tan.x);\n"
                                               "    o_rgba = vec4(env(d + u_up * (ny * u_tan.y)), 0.0);\n"
                                               "}\n";

static const char *const bench_fs_down =
    "#version 330 core\n"
    "uniform sampler2D u_src;\n"
    "uniform int u_k;\n"
    "out vec4 o_rgba;\n"
    "void main() {\n"
    "    ivec2 p = ivec2(gl_FragCoord.xy) * u_k;\n"
    "    vec4 s = vec4(0.0);\n"
    "    for (int t = 0; t < u_k; t++)\n"
    "        for (int x = 0; x < u_k; x++) s += texelFetch(u_src, p + ivec2(x, t), 0);\n"
    "    o_rgba = s / float(u_k * u_k);\n"
    "}\n";

static void bench_die(const char *msg)
{
    printf("{\"ok\": false, \"error\": \"%s\"}\n", msg);
    exit(1);
}

static GLuint bench_shader(GLenum kind, const char *src)
{
    GLuint sh = glCreateShader(kind);
    glShaderSource(sh, 1, &src, NULL);
    glCompileShader(sh);
    GLint ok = 0;
    glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetShaderInfoLog(sh, sizeof log, NULL, log);
        fprintf(stderr, "bench_llvmpipe: GLSL compile error: %s\n", log);
        bench_die("shader compile failed; see stderr");
    }
    return sh;
}

static GLuint bench_program(const char *vs, const char *fs)
{
    GLuint p = glCreateProgram();
    glAttachShader(p, bench_shader(GL_VERTEX_SHADER, vs));
    glAttachShader(p, bench_shader(GL_FRAGMENT_SHADER, fs));
    glLinkProgram(p);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok)
        bench_die("program link failed");
    return p;
}

static GLint bench_loc(GLuint p, const char *name) { return glGetUniformLocation(p, name); }

static void bench_set_camera(GLuint p, const render_camera *cam)
{
    glUseProgram(p);
    glUniform3f(bench_loc(p, "u_eye"), cam->eye.x, cam->eye.y, cam->eye.z);
    glUniform3f(bench_loc(p, "u_right"), cam->right.x, cam->right.y, cam->right.z);
    glUniform3f(bench_loc(p, "u_up"), cam->up.x, cam->up.y, cam->up.z);
    glUniform3f(bench_loc(p, "u_fwd"), cam->forward.x, cam->forward.y, cam->forward.z);
    glUniform2f(bench_loc(p, "u_tan"), cam->tan_half_x, cam->tan_half_y);
    /* Nothing in the scene is nearer than 1 m or farther than 30 m from the eye. */
    glUniform1f(bench_loc(p, "u_near"), 0.05f);
    glUniform1f(bench_loc(p, "u_far"), 100.0f);
    glUniform1i(bench_loc(p, "u_env"), 0);
}

static void bench_set_material(GLuint p, const material *m)
{
    const d3d_params *d = &m->d3d;
    const d3d9client_params *c = &m->d9;
    glUniform3f(bench_loc(p, "u_vd"), d->diffuse.x, d->diffuse.y, d->diffuse.z);
    glUniform3f(bench_loc(p, "u_vs"), d->specular.x, d->specular.y, d->specular.z);
    glUniform3f(bench_loc(p, "u_ve"), d->emissive.x, d->emissive.y, d->emissive.z);
    glUniform1f(bench_loc(p, "u_power"), d->power);
    glUniform3f(bench_loc(p, "u_lambda"), c->reflect.x, c->reflect.y, c->reflect.z);
    glUniform3f(bench_loc(p, "u_fcol"), c->fresnel_colour.x, c->fresnel_colour.y, c->fresnel_colour.z);
    glUniform1f(bench_loc(p, "u_r0"), c->r0);
    glUniform1f(bench_loc(p, "u_m"), c->m);
    glUniform1f(bench_loc(p, "u_fp"), c->p);
    glUniform1f(bench_loc(p, "u_dw"), 1.0f - v3_max_comp(c->reflect));
}

static int bench_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    const char *scene_path = "tests/bench/bench_scene.yaml", *out_path = NULL;
    int size = 1024, k = 4, tris = 10000, threads = 1, reps = 3, prepass = 1;
    for (int i = 1; i + 1 < argc; i += 2) {
        const char *a = argv[i], *v = argv[i + 1];
        if (!strcmp(a, "--scene"))
            scene_path = v;
        else if (!strcmp(a, "--size"))
            size = atoi(v);
        else if (!strcmp(a, "--k"))
            k = atoi(v);
        else if (!strcmp(a, "--tris"))
            tris = atoi(v);
        else if (!strcmp(a, "--threads"))
            threads = atoi(v);
        else if (!strcmp(a, "--reps"))
            reps = atoi(v);
        else if (!strcmp(a, "--prepass"))
            prepass = atoi(v);
        else if (!strcmp(a, "--out"))
            out_path = v;
        else {
            fprintf(stderr,
                    "bench_llvmpipe: unknown option %s; see the usage comment in tests/bench/bench_llvmpipe.c\n", a);
            return 2;
        }
    }
    if (size < 1 || k < 1 || k > 16 || reps < 1 || reps > 64 || threads < 1)
        bench_die("bad --size/--k/--reps/--threads");
    char buf[32];
    snprintf(buf, sizeof buf, "%d", threads);
    setenv("LP_NUM_THREADS", buf, 1);

    scene s;
    env_map env;
    float *env_px = NULL;
    mesh m;
    char err[512];
    if (bench_frame_load(scene_path, BENCH_SCENE_REFLECT, tris, &s, &env, &env_px, &m, err, sizeof err) != RC_OK) {
        fprintf(stderr, "bench_llvmpipe: %s\n", err);
        bench_die("scene, environment or mesh not loaded; see stderr");
    }
    if (env.kind != ENV_IMAGE)
        bench_die("the GLSL twin needs an image environment");
    for (int o = 0; o < s.n_objects; o++) {
        const material *mt = &s.materials[s.objects[o].material];
        if (mt->model != MODEL_D3D9CLIENT || mt->d9.sun_angle || mt->d9.norm != NORM_MAX || mt->d3d.per_vertex ||
            mt->d3d.clamp || !mt->d3d.local_viewer || v3_max_comp(mt->d3d.ambient) != 0.0f)
            bench_die("the GLSL twin implements D3D9Client with local viewer, max norm, no ambient, per pixel");
    }
    for (int i = 0; i < s.n_lights; i++) {
        const light *l = &s.lights[i];
        if (l->kind == LIGHT_SPOT ||
            (l->kind == LIGHT_POINT && (l->a0 != 0 || l->a1 != 0 || l->a2 != 1 || isfinite(l->range))) ||
            v3_max_comp(l->ambient) != 0.0f || v3_max_comp(s.global_ambient) != 0.0f)
            bench_die("the GLSL twin handles sun and 1/d^2 point lights without ambient only");
    }

    int attribs[] = {OSMESA_FORMAT,
                     OSMESA_RGBA,
                     OSMESA_DEPTH_BITS,
                     0,
                     OSMESA_PROFILE,
                     OSMESA_CORE_PROFILE,
                     OSMESA_CONTEXT_MAJOR_VERSION,
                     3,
                     OSMESA_CONTEXT_MINOR_VERSION,
                     3,
                     0};
    OSMesaContext ctx = OSMesaCreateContextAttribs(attribs, NULL);
    if (!ctx)
        bench_die("OSMesaCreateContextAttribs failed (core 3.3)");
    static unsigned char dummy[4 * 16 * 16];
    if (!OSMesaMakeCurrent(ctx, dummy, GL_UNSIGNED_BYTE, 16, 16))
        bench_die("OSMesaMakeCurrent failed");

    int big_w = size * k, big_h = size * k;
    GLint max_rb = 0, max_tex = 0, max_vp[2] = {0, 0};
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
    glGetIntegerv(GL_MAX_VIEWPORT_DIMS, max_vp);
    if (big_w > max_rb || big_w > max_tex || big_w > max_vp[0] || big_h > max_vp[1])
        bench_die("the supersampled target exceeds llvmpipe's maximum size");

    render_camera cam;
    render_camera_make(&s, size, size, &cam);
    GLuint p_shade = bench_program(bench_vs_mesh, bench_fs_shade);
    GLuint p_depth = bench_program(bench_vs_mesh, bench_fs_depth);
    GLuint p_bg = bench_program(bench_vs_full, bench_fs_background);
    GLuint p_down = bench_program(bench_vs_full, bench_fs_down);
    bench_set_camera(p_shade, &cam);
    bench_set_camera(p_depth, &cam);
    bench_set_camera(p_bg, &cam);
    glUseProgram(p_bg);
    glUniform2f(bench_loc(p_bg, "u_size"), (float)size, (float)size);
    glUniform1f(bench_loc(p_bg, "u_k"), (float)k);
    glUniform3f(bench_loc(p_bg, "u_env_scale"), env.scale.x, env.scale.y, env.scale.z);
    glUseProgram(p_down);
    glUniform1i(bench_loc(p_down, "u_src"), 1);
    glUniform1i(bench_loc(p_down, "u_k"), k);
    glUseProgram(p_shade);
    glUniform3f(bench_loc(p_shade, "u_env_scale"), env.scale.x, env.scale.y, env.scale.z);
    glUniform1i(bench_loc(p_shade, "u_nlights"), s.n_lights);
    for (int i = 0; i < s.n_lights; i++) {
        const light *l = &s.lights[i];
        char name[32];
        vec3 pos = l->kind == LIGHT_SUN ? v3_neg(v3_norm(l->direction)) : l->position;
        snprintf(name, sizeof name, "u_lpos[%d]", i);
        glUniform4f(bench_loc(p_shade, name), pos.x, pos.y, pos.z, l->kind == LIGHT_SUN ? 0.0f : 1.0f);
        snprintf(name, sizeof name, "u_lint[%d]", i);
        glUniform3f(bench_loc(p_shade, name), l->intensity.x, l->intensity.y, l->intensity.z);
    }

    GLuint tex_env, tex_big, tex_small, rb_depth, fbo_big, fbo_small, vao, vbo[2];
    glGenTextures(1, &tex_env);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, tex_env);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, env.width, env.height, 0, GL_RGB, GL_FLOAT, env.rgb);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);

    glGenTextures(1, &tex_big);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, tex_big);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, big_w, big_h, 0, GL_RGBA, GL_FLOAT, NULL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glGenRenderbuffers(1, &rb_depth);
    glBindRenderbuffer(GL_RENDERBUFFER, rb_depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, big_w, big_h);
    glGenFramebuffers(1, &fbo_big);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_big);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex_big, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rb_depth);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        bench_die("big FBO incomplete");

    glGenTextures(1, &tex_small);
    glActiveTexture(GL_TEXTURE2);
    glBindTexture(GL_TEXTURE_2D, tex_small);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, size, size, 0, GL_RGBA, GL_FLOAT, NULL);
    glGenFramebuffers(1, &fbo_small);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_small);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex_small, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        bench_die("small FBO incomplete");
    glActiveTexture(GL_TEXTURE0);

    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glGenBuffers(2, vbo);
    float *inter = malloc((size_t)m.n_verts * 6 * sizeof *inter);
    if (!inter)
        bench_die("out of memory");
    for (int i = 0; i < m.n_verts; i++) {
        memcpy(inter + 6 * (size_t)i, &m.pos[i], 3 * sizeof(float));
        memcpy(inter + 6 * (size_t)i + 3, &m.nrm[i], 3 * sizeof(float));
    }
    glBindBuffer(GL_ARRAY_BUFFER, vbo[0]);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)m.n_verts * 6 * sizeof(float)), inter, GL_STATIC_DRAW);
    free(inter);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, vbo[1]);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)((size_t)m.n_tris * 3 * sizeof(uint32_t)), m.idx, GL_STATIC_DRAW);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), (void *)0);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), (void *)(3 * sizeof(float)));
    glEnableVertexAttribArray(0);
    glEnableVertexAttribArray(1);

    /* Objects are contiguous triangle ranges in the bench mesh; one draw per object. */
    int first[SCENE_MAX_OBJECTS + 1], count[SCENE_MAX_OBJECTS];
    for (int o = 0; o < s.n_objects; o++) {
        first[o] = -1;
        count[o] = 0;
    }
    for (int t = 0; t < m.n_tris; t++) {
        int o = m.tri_object[t];
        if (first[o] < 0)
            first[o] = t;
        if (first[o] + count[o] != t)
            bench_die("object triangles not contiguous");
        count[o]++;
    }

    float *px = malloc((size_t)size * size * 4 * sizeof *px);
    double *ms = malloc((size_t)(reps + 1) * sizeof *ms);
    if (!px || !ms)
        bench_die("out of memory");
    glDisable(GL_CULL_FACE);
    glEnable(GL_DEPTH_TEST);
    glClearDepth(1.0);
    /* Frame 0 compiles llvmpipe's shader variants and touches the targets: not timed. */
    for (int r = 0; r <= reps; r++) {
        double t0 = bench_now();
        glBindFramebuffer(GL_FRAMEBUFFER, fbo_big);
        glViewport(0, 0, big_w, big_h);
        glDepthMask(GL_TRUE);
        glClear(GL_DEPTH_BUFFER_BIT);
        if (prepass) {
            glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
            glDepthFunc(GL_LESS);
            glUseProgram(p_depth);
            for (int o = 0; o < s.n_objects; o++)
                if (count[o])
                    glDrawElements(GL_TRIANGLES, 3 * count[o], GL_UNSIGNED_INT,
                                   (void *)(3 * sizeof(uint32_t) * (size_t)first[o]));
            glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
            glDepthFunc(GL_EQUAL);
            glDepthMask(GL_FALSE);
        } else {
            glDepthFunc(GL_LESS);
        }
        glUseProgram(p_shade);
        for (int o = 0; o < s.n_objects; o++) {
            if (!count[o])
                continue;
            bench_set_material(p_shade, &s.materials[s.objects[o].material]);
            glDrawElements(GL_TRIANGLES, 3 * count[o], GL_UNSIGNED_INT,
                           (void *)(3 * sizeof(uint32_t) * (size_t)first[o]));
        }
        glDepthFunc(GL_LEQUAL);
        glDepthMask(GL_FALSE);
        glUseProgram(p_bg);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo_small);
        glViewport(0, 0, size, size);
        glDisable(GL_DEPTH_TEST);
        glUseProgram(p_down);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glReadPixels(0, 0, size, size, GL_RGBA, GL_FLOAT, px);
        glEnable(GL_DEPTH_TEST);
        ms[r] = 1e3 * (bench_now() - t0);
    }
    if (glGetError() != GL_NO_ERROR)
        bench_die("GL error during the frame");
    double first_ms = ms[0];
    qsort(ms + 1, (size_t)reps, sizeof *ms, bench_cmp_double);
    double median = reps % 2 ? ms[1 + reps / 2] : 0.5 * (ms[reps / 2] + ms[1 + reps / 2]);

    if (out_path) {
        /* GL row 0 is the bottom; the bench image has row 0 at the top. */
        size_t n = (size_t)size * size;
        float *planes = malloc(3 * n * sizeof *planes);
        if (!planes)
            bench_die("out of memory");
        for (int y = 0; y < size; y++)
            for (int x = 0; x < size; x++)
                for (int c = 0; c < 3; c++)
                    planes[c * n + (size_t)y * size + x] = px[4 * ((size_t)(size - 1 - y) * size + x) + c];
        const float *ch[3] = {planes, planes + n, planes + 2 * n};
        if (bench_image_write(out_path, size, size, 3, ch) != 0)
            bench_die("cannot write --out");
        free(planes);
    }
    printf("{\"ok\": true, \"renderer\": \"%s\", \"gl_version\": \"%s\", \"size\": %d, \"k\": %d, \"tris\": %d, "
           "\"threads\": %d, \"prepass\": %d, \"reps\": %d, \"first_ms\": %.3f, \"ms_median\": %.3f, \"ms_min\": %.3f, "
           "\"ms_max\": %.3f}\n",
           (const char *)glGetString(GL_RENDERER), (const char *)glGetString(GL_VERSION), size, k, m.n_tris, threads,
           prepass, reps, first_ms, median, ms[1], ms[reps]);
    free(px);
    free(ms);
    OSMesaDestroyContext(ctx);
    mesh_free(&m);
    free(env_px);
    return 0;
}
