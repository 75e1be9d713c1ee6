/* libFuzzer target: the YAML scene parser (harness/scene_file.h), then the models on what it
 * accepts. The input is passed without a terminating NUL, so a read past len is caught by
 * AddressSanitizer. A scene the parser accepts is shaded at a few fixed points: docs/models.md
 * section 5 says bad input is rejected where it enters, so an accepted scene that makes
 * shade_eval, or the SIMD batch form shade_eval_n the shading loop runs, produce NaN or Inf is
 * a finding (the fuzzer aborts with the input). Relative
 * paths in the scene resolve against the current directory (run it from scenes/ so the
 * seed corpus's environment images are found). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scene_file.h"
#include "shade.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int fuzz_scene_finite(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

static void fuzz_scene_check(const scene *s, int m, const char *path, int i, const char *form, const shade_terms *t)
{
    if (fuzz_scene_finite(t->diffuse) && fuzz_scene_finite(t->specular) && fuzz_scene_finite(t->reflection) &&
        fuzz_scene_finite(t->emission) && isfinite(t->alpha))
        return;
    fprintf(stderr,
            "fuzz_scene: accepted scene gives non-finite shading (%s): material %d (%s, path %s) "
            "at point %d: diffuse %g %g %g specular %g %g %g reflection %g %g %g alpha %g\n",
            form, m, s->materials[m].name, path, i, t->diffuse.x, t->diffuse.y, t->diffuse.z, t->specular.x,
            t->specular.y, t->specular.z, t->reflection.x, t->reflection.y, t->reflection.z, t->alpha);
    abort();
}

static void fuzz_scene_shade(const scene *s)
{
    /* A constant environment stands in for any image: the models only see its radiance. */
    env_map env = {
        .kind = s->env.kind == ENV_NONE ? ENV_NONE : ENV_CONSTANT, .constant = s->env.radiance, .scale = v3s(1.0f)};
    shade_context c;
    shade_context_make(s, &env, &c);
    static const float pts[3][3] = {{0.0f, 0.0f, 0.0f}, {0.3f, -0.2f, 0.1f}, {-1.0f, 0.5f, 2.0f}};
    static const float nrm[3][3] = {{0.0f, 1.0f, 0.0f}, {0.6f, 0.0f, 0.8f}, {0.0f, 0.0f, 1.0f}};
    for (int m = 0; m < s->n_materials; m++) {
        shade_plan p;
        shade_plan_make(&c, &s->materials[m], &p);
        static shade_batch_in in;
        static shade_batch_out out;
        in.n = 3;
        for (int i = 0; i < 3; i++) {
            vec3 x = v3(pts[i][0], pts[i][1], pts[i][2]);
            vec3 n = v3(nrm[i][0], nrm[i][1], nrm[i][2]);
            vec3 v = v3_norm(v3_sub(s->camera.eye, x));
            if (v3_dot(v, v) == 0.0f)
                v = n; /* eye at the point: look along the normal */
            if (v3_dot(n, v) < 0.0f)
                n = v3_neg(n); /* shade_eval wants n facing the viewer */
            shade_terms t;
            shade_eval(&c, &p, x, n, v, &t);
            fuzz_scene_check(s, m, p.path, i, "shade_eval", &t);
            shade_batch_set_input(&in, i, x, n, v);
        }
        shade_eval_n(&c, &p, &in, &out);
        for (int i = 0; i < 3; i++) {
            shade_terms t;
            shade_batch_get_terms(&out, i, &t);
            fuzz_scene_check(s, m, p.path, i, "shade_eval_n", &t);
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static scene s; /* ~100 KB: static, not on the fuzzer's stack */
    char err[512];
    /* A copy of exactly size bytes, so ASan sees any read past the end. */
    char *text = malloc(size ? size : 1);
    if (!text)
        return 0;
    if (size)
        memcpy(text, data, size);
    err[0] = '\0';
    rc_status st = scene_file_parse(text, size, NULL, &s, err, sizeof err);
    if (st != RC_OK) {
        /* The contract: one line naming the place. */
        if (memchr(err, '\0', sizeof err) == NULL || err[0] == '\0') {
            fprintf(stderr, "fuzz_scene: status %d without a message\n", (int)st);
            abort();
        }
    } else {
        if (s.n_lights < 0 || s.n_lights > SCENE_MAX_LIGHTS || s.n_materials < 0 ||
            s.n_materials > SCENE_MAX_MATERIALS || s.n_objects < 0 || s.n_objects > SCENE_MAX_OBJECTS) {
            fprintf(stderr, "fuzz_scene: accepted scene with counts out of range\n");
            abort();
        }
        fuzz_scene_shade(&s);
    }
    free(text);
    return 0;
}
