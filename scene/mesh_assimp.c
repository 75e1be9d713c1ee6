/* mesh_assimp.c - assets through Open Asset Import Library's C API (scene/mesh_assimp.h).
 *
 * One short function per object of the format: a mesh (mas_mesh), a material (mas_material_read),
 * its texture (mas_texture); the child-process wrapper (mas_child) around both imports.
 */
#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "fileio.h"
#include "mesh_assimp.h"

/* Vertices and triangles of one import: the OBJ/PLY readers' own bound (int indices), far above
 * what a 1 GiB file (FILEIO_MESH_MAX_BYTES) can describe. */
#define MAS_MAX_ITEMS (INT_MAX / 4)

int mesh_assimp_supported(const char *path)
{
    const char *dot = strrchr(path, '.');
    if (!dot || strchr(dot, '/'))
        return 0;
    return aiIsExtensionSupported(dot) == AI_TRUE;
}

void mesh_assimp_soup_free(mesh_assimp_soup *g)
{
    free(g->pos);
    free(g->nrm);
    free(g->uv);
    free(g->has_uv);
    free(g->idx);
    memset(g, 0, sizeof *g);
}

/* The import every caller shares: triangles only, node transforms applied, no normals invented
 * (scene/mesh_soup.c computes missing ones by its own rule, as for OBJ and PLY). */
static const struct aiScene *mas_open(const char *path, char *err, size_t errlen)
{
    int fd;
    char why[SCENE_PATH_MAX + 200];
    if (fileio_open_input(path, FILEIO_MESH_MAX_BYTES, "an asset file", &fd, NULL, why, sizeof why) != RC_OK) {
        status_message(err, errlen, "%s", why);
        return NULL;
    }
    close(fd);
    struct aiPropertyStore *props = aiCreatePropertyStore();
    aiSetImportPropertyInteger(props, AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    const struct aiScene *sc = aiImportFileExWithProperties(path,
                                                            aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                                                aiProcess_PreTransformVertices | aiProcess_SortByPType |
                                                                aiProcess_ValidateDataStructure,
                                                            NULL, props);
    aiReleasePropertyStore(props);
    if (!sc) {
        const char *e = aiGetErrorString();
        char one[300];
        snprintf(one, sizeof one, "%s", e && e[0] ? e : "no reason given");
        for (char *p = one; *p; p++)
            if (*p == '\n' || *p == '\r')
                *p = ' ';
        status_message(err, errlen, "%s: libassimp refused the asset: %s; fix: re-export it (glTF 2.0 is best read)",
                       path, one);
    }
    return sc;
}

static void mas_material_name(const struct aiScene *sc, unsigned mi, char *out, size_t len)
{
    struct aiString s;
    out[0] = '\0';
    if (mi < sc->mNumMaterials && aiGetMaterialString(sc->mMaterials[mi], AI_MATKEY_NAME, &s) == aiReturn_SUCCESS)
        snprintf(out, len, "%s", s.data);
}

/* Appends one mesh's triangles to g (arrays already sized). */
static void mas_mesh(const struct aiMesh *am, mesh_assimp_soup *g)
{
    int base = g->n_verts;
    for (unsigned v = 0; v < am->mNumVertices; v++) {
        int o = base + (int)v;
        g->pos[3 * o] = am->mVertices[v].x;
        g->pos[3 * o + 1] = am->mVertices[v].y;
        g->pos[3 * o + 2] = am->mVertices[v].z;
        g->nrm[3 * o] = am->mNormals ? am->mNormals[v].x : NAN;
        g->nrm[3 * o + 1] = am->mNormals ? am->mNormals[v].y : NAN;
        g->nrm[3 * o + 2] = am->mNormals ? am->mNormals[v].z : NAN;
        g->has_uv[o] = am->mTextureCoords[0] != NULL;
        g->uv[2 * o] = am->mTextureCoords[0] ? am->mTextureCoords[0][v].x : 0.0;
        g->uv[2 * o + 1] = am->mTextureCoords[0] ? am->mTextureCoords[0][v].y : 0.0;
    }
    g->n_verts += (int)am->mNumVertices;
    for (unsigned f = 0; f < am->mNumFaces; f++) {
        const struct aiFace *fc = &am->mFaces[f];
        if (fc->mNumIndices != 3 || fc->mIndices[0] >= am->mNumVertices || fc->mIndices[1] >= am->mNumVertices ||
            fc->mIndices[2] >= am->mNumVertices)
            continue;
        for (int c = 0; c < 3; c++)
            g->idx[3 * g->n_tris + c] = base + (int)fc->mIndices[c];
        g->n_tris++;
    }
}

static int mas_selected(const struct aiScene *sc, const struct aiMesh *am, const char *material_name)
{
    char name[SCENE_NAME_MAX];
    if (!material_name || !material_name[0])
        return 1;
    mas_material_name(sc, am->mMaterialIndex, name, sizeof name);
    return strcmp(name, material_name) == 0;
}

/* The asset's material names, for the message when none matches. */
static void mas_material_names(const struct aiScene *sc, char *out, size_t len)
{
    size_t used = 0;
    out[0] = '\0';
    for (unsigned i = 0; i < sc->mNumMaterials && used + 1 < len; i++) {
        char name[SCENE_NAME_MAX];
        mas_material_name(sc, i, name, sizeof name);
        int w = snprintf(out + used, len - used, "%s'%s'", i ? ", " : "", name);
        used += w > 0 ? (size_t)w : 0;
    }
}

rc_status mesh_assimp_import(const char *path, const char *material_name, mesh_assimp_soup *out, char *err,
                             size_t errlen)
{
    memset(out, 0, sizeof *out);
    const struct aiScene *sc = mas_open(path, err, errlen);
    if (!sc)
        return RC_ERR_PARSE;
    size_t nv = 0, nt = 0;
    for (unsigned i = 0; i < sc->mNumMeshes; i++)
        if (mas_selected(sc, sc->mMeshes[i], material_name)) {
            nv += sc->mMeshes[i]->mNumVertices;
            nt += sc->mMeshes[i]->mNumFaces;
        }
    rc_status rc = RC_OK;
    if (nt == 0) {
        char names[300];
        mas_material_names(sc, names, sizeof names);
        if (material_name && material_name[0])
            status_message(err, errlen, "%s: no triangles with material '%s'; fix: usemtl one of %s", path,
                           material_name, names[0] ? names : "(the asset names none)");
        else
            status_message(err, errlen, "%s: the asset has no triangles; fix: an asset with a surface mesh", path);
        rc = RC_ERR_RANGE;
    } else if (nv > MAS_MAX_ITEMS || nt > MAS_MAX_ITEMS) {
        status_message(err, errlen, "%s: %zu vertices, %zu triangles; fix: at most %d of each", path, nv, nt,
                       MAS_MAX_ITEMS);
        rc = RC_ERR_RANGE;
    } else {
        out->pos = malloc(nv * 3 * sizeof *out->pos);
        out->nrm = malloc(nv * 3 * sizeof *out->nrm);
        out->uv = malloc(nv * 2 * sizeof *out->uv);
        out->has_uv = malloc(nv);
        out->idx = malloc(nt * 3 * sizeof *out->idx);
        if (!out->pos || !out->nrm || !out->uv || !out->has_uv || !out->idx) {
            status_message(err, errlen, "%s: out of memory importing the asset; fix: a smaller asset", path);
            rc = RC_ERR_NOMEM;
        }
        for (unsigned i = 0; rc == RC_OK && i < sc->mNumMeshes; i++)
            if (mas_selected(sc, sc->mMeshes[i], material_name))
                mas_mesh(sc->mMeshes[i], out);
    }
    aiReleaseImport(sc);
    if (rc != RC_OK)
        mesh_assimp_soup_free(out);
    return rc;
}

/* A material's texture: an image file next to the asset. Textures inside the asset ("*0", glTF
 * data URIs, GLB buffers) have no file the reference renderers could read: refused. */
static rc_status mas_texture(const struct aiMaterial *am, const char *path, mesh_assimp_material *out, char *err,
                             size_t errlen)
{
    struct aiString t;
    if (aiGetMaterialTexture(am, aiTextureType_BASE_COLOR, 0, &t, NULL, NULL, NULL, NULL, NULL, NULL) !=
            aiReturn_SUCCESS &&
        aiGetMaterialTexture(am, aiTextureType_DIFFUSE, 0, &t, NULL, NULL, NULL, NULL, NULL, NULL) != aiReturn_SUCCESS)
        return RC_OK;
    if (t.data[0] == '*' || strncmp(t.data, "data:", 5) == 0) {
        status_message(err, errlen,
                       "%s: material '%s': its texture is embedded in the asset; fix: export the texture as a "
                       "separate image file",
                       path, out->name);
        return RC_ERR_RANGE;
    }
    /* Exporters write the authoring machine's path ("C:\\art\\top.tga"): Windows separators
     * become '/', and a path that is not there is looked for by its base name next to the asset. */
    for (char *q = t.data; *q; q++)
        if (*q == '\\')
            *q = '/';
    const char *slash = strrchr(path, '/'), *base = strrchr(t.data, '/');
    int dir = slash ? (int)(slash - path + 1) : 0;
    const char *name = t.data;
    if (t.data[0] == '/' || strchr(t.data, ':'))
        name = base ? base + 1 : t.data;
    if ((size_t)dir + strlen(name) + 1 > sizeof out->texture) {
        status_message(err, errlen, "%s: material '%s': texture path too long; fix: at most %d bytes", path, out->name,
                       SCENE_PATH_MAX - 1);
        return RC_ERR_RANGE;
    }
    snprintf(out->texture, sizeof out->texture, "%.*s%s", dir, path, name);
    if (access(out->texture, F_OK) != 0 && base && name != base + 1)
        snprintf(out->texture, sizeof out->texture, "%.*s%s", dir, path, base + 1);
    return RC_OK;
}

static int mas_colour(const struct aiMaterial *am, const char *key, vec3 *out)
{
    struct aiColor4D c;
    if (aiGetMaterialColor(am, key, 0, 0, &c) != aiReturn_SUCCESS)
        return 0;
    *out = v3(c.r, c.g, c.b);
    return isfinite(c.r) && isfinite(c.g) && isfinite(c.b);
}

static int mas_float(const struct aiMaterial *am, const char *key, float *out)
{
    ai_real v;
    unsigned n = 1;
    if (aiGetMaterialFloatArray(am, key, 0, 0, &v, &n) != aiReturn_SUCCESS || n != 1 || !isfinite(v))
        return 0;
    *out = (float)v;
    return 1;
}

/* One material's keys, as the file states them. */
static rc_status mas_material_read(const struct aiMaterial *am, const char *path, mesh_assimp_material *out, char *err,
                                   size_t errlen)
{
    float metal = 0.0f, rough = 1.0f;
    int has_metal = mas_float(am, "$mat.metallicFactor", &metal);
    int has_rough = mas_float(am, "$mat.roughnessFactor", &rough);
    out->pbr = has_metal || has_rough;
    /* glTF's defaults when a factor is absent: metallic 1, roughness 1 (glTF 2.0 spec, 5.19). */
    out->metallic = has_metal ? metal : 1.0f;
    out->roughness = has_rough ? rough : 1.0f;
    out->has_base = mas_colour(am, "$clr.base", &out->base);
    out->has_diffuse = mas_colour(am, "$clr.diffuse", &out->diffuse);
    out->has_specular = mas_colour(am, "$clr.specular", &out->specular);
    out->has_emissive = mas_colour(am, "$clr.emissive", &out->emissive);
    out->has_ambient = mas_colour(am, "$clr.ambient", &out->ambient);
    out->has_power = mas_float(am, "$mat.shininess", &out->power);
    return mas_texture(am, path, out, err, errlen);
}

rc_status mesh_assimp_material_import(const char *path, const char *material_name, mesh_assimp_material *out, char *err,
                                      size_t errlen)
{
    memset(out, 0, sizeof *out);
    const struct aiScene *sc = mas_open(path, err, errlen);
    if (!sc)
        return RC_ERR_PARSE;
    rc_status rc = RC_ERR_RANGE;
    for (unsigned i = 0; i < sc->mNumMaterials && rc == RC_ERR_RANGE; i++) {
        char name[SCENE_NAME_MAX];
        mas_material_name(sc, i, name, sizeof name);
        if (strcmp(name, material_name) != 0)
            continue;
        snprintf(out->name, sizeof out->name, "%s", name);
        rc = mas_material_read(sc->mMaterials[i], path, out, err, errlen);
    }
    if (rc == RC_ERR_RANGE && !out->name[0]) {
        char names[300];
        mas_material_names(sc, names, sizeof names);
        status_message(err, errlen, "%s: no material '%s'; fix: one of %s", path, material_name,
                       names[0] ? names : "(the asset names none)");
    }
    aiReleaseImport(sc);
    return rc;
}

/* --- the child process ------------------------------------------------------------------- */

typedef struct {
    int rc;
    int n_verts, n_tris;
    char msg[512];
} mas_header;

static int mas_write(int fd, const void *p, size_t n)
{
    const char *c = p;
    while (n > 0) {
        ssize_t w = write(fd, c, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return 0;
        c += w;
        n -= (size_t)w;
    }
    return 1;
}

static int mas_read(int fd, void *p, size_t n)
{
    char *c = p;
    while (n > 0) {
        ssize_t r = read(fd, c, n);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return 0;
        c += r;
        n -= (size_t)r;
    }
    return 1;
}

/* What the child does: import, then write the header and the payload. */
typedef void (*mas_job)(int fd, const char *path, const char *name, void *result);

static void mas_mesh_job(int fd, const char *path, const char *name, void *result)
{
    (void)result;
    mas_header h = {0};
    mesh_assimp_soup g;
    h.rc = (int)mesh_assimp_import(path, name, &g, h.msg, sizeof h.msg);
    h.n_verts = g.n_verts;
    h.n_tris = g.n_tris;
    size_t v = (size_t)g.n_verts, t = (size_t)g.n_tris;
    if (mas_write(fd, &h, sizeof h) && h.rc == RC_OK && mas_write(fd, g.pos, 3 * v * sizeof *g.pos) &&
        mas_write(fd, g.nrm, 3 * v * sizeof *g.nrm) && mas_write(fd, g.uv, 2 * v * sizeof *g.uv) &&
        mas_write(fd, g.has_uv, v))
        mas_write(fd, g.idx, 3 * t * sizeof *g.idx);
    mesh_assimp_soup_free(&g);
}

static void mas_material_job(int fd, const char *path, const char *name, void *result)
{
    (void)result;
    mas_header h = {0};
    mesh_assimp_material m;
    h.rc = (int)mesh_assimp_material_import(path, name, &m, h.msg, sizeof h.msg);
    if (mas_write(fd, &h, sizeof h) && h.rc == RC_OK)
        mas_write(fd, &m, sizeof m);
}

/* The parent's side of the mesh job: the payload, with counts checked before allocating. */
static rc_status mas_mesh_receive(int fd, const mas_header *h, void *result)
{
    mesh_assimp_soup *g = result;
    if (h->n_verts <= 0 || h->n_tris <= 0 || h->n_verts > MAS_MAX_ITEMS || h->n_tris > MAS_MAX_ITEMS)
        return RC_ERR_PARSE;
    size_t v = (size_t)h->n_verts, t = (size_t)h->n_tris;
    g->pos = malloc(3 * v * sizeof *g->pos);
    g->nrm = malloc(3 * v * sizeof *g->nrm);
    g->uv = malloc(2 * v * sizeof *g->uv);
    g->has_uv = malloc(v);
    g->idx = malloc(3 * t * sizeof *g->idx);
    if (!g->pos || !g->nrm || !g->uv || !g->has_uv || !g->idx)
        return RC_ERR_NOMEM;
    if (!mas_read(fd, g->pos, 3 * v * sizeof *g->pos) || !mas_read(fd, g->nrm, 3 * v * sizeof *g->nrm) ||
        !mas_read(fd, g->uv, 2 * v * sizeof *g->uv) || !mas_read(fd, g->has_uv, v) ||
        !mas_read(fd, g->idx, 3 * t * sizeof *g->idx))
        return RC_ERR_PARSE;
    g->n_verts = h->n_verts;
    g->n_tris = h->n_tris;
    for (size_t i = 0; i < 3 * t; i++)
        if (g->idx[i] < 0 || g->idx[i] >= h->n_verts)
            return RC_ERR_PARSE;
    return RC_OK;
}

static rc_status mas_material_receive(int fd, const mas_header *h, void *result)
{
    (void)h;
    mesh_assimp_material *m = result;
    if (!mas_read(fd, m, sizeof *m))
        return RC_ERR_PARSE;
    m->name[sizeof m->name - 1] = '\0';
    m->texture[sizeof m->texture - 1] = '\0';
    return RC_OK;
}

/* The child's heap bound: what it has now plus the memory limit (core/fileio.h), so that an
 * importer asking for absurd sizes (seen: 25 GB for a 1 kB file) fails at once instead of paging
 * the machine. Not under AddressSanitizer, whose shadow memory counts as data. */
static void mas_child_limit(void)
{
#if defined(__SANITIZE_ADDRESS__)
    return;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    return;
#endif
#endif
    size_t lim;
    char why[200];
    unsigned long long kb = 0;
    char line[128];
    FILE *f = fopen("/proc/self/status", "r");
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "VmData: %llu kB", &kb) == 1)
            break;
    if (f)
        fclose(f);
    if (kb == 0 || fileio_memory_limit(&lim, why, sizeof why) != RC_OK)
        return;
    struct rlimit r;
    r.rlim_cur = r.rlim_max = (rlim_t)(kb * 1024 + lim);
    setrlimit(RLIMIT_DATA, &r);
}

/* Runs job in a child; the parent receives. A child that dies is a one-line error. */
static rc_status mas_child(const char *path, const char *name, mas_job job,
                           rc_status (*receive)(int, const mas_header *, void *), void *result, char *err,
                           size_t errlen)
{
    int p[2];
    if (pipe(p) != 0) {
        status_message(err, errlen, "%s: cannot start the import (pipe: %s); fix: free file descriptors", path,
                       strerror(errno));
        return RC_ERR_IO;
    }
    fflush(NULL); /* nothing buffered may be written twice */
    pid_t pid = fork();
    if (pid < 0) {
        close(p[0]);
        close(p[1]);
        status_message(err, errlen, "%s: cannot start the import (fork: %s); fix: free memory or processes", path,
                       strerror(errno));
        return RC_ERR_IO;
    }
    if (pid == 0) {
        close(p[0]);
        /* libassimp's parsers print to stdout and stderr themselves (OpenDDL: "nullptr returned
         * by creating DDLNode."); the one line reflcheck prints is the parent's. */
        int null = open("/dev/null", O_WRONLY);
        if (null >= 0) {
            dup2(null, STDOUT_FILENO);
            dup2(null, STDERR_FILENO);
            close(null);
        }
        mas_child_limit();
        job(p[1], path, name ? name : "", NULL);
        _exit(0);
    }
    close(p[1]);
    mas_header h;
    int got = mas_read(p[0], &h, sizeof h);
    rc_status rc = RC_ERR_PARSE;
    if (got && h.rc != RC_OK) {
        h.msg[sizeof h.msg - 1] = '\0';
        status_message(err, errlen, "%s", h.msg);
        rc = (rc_status)h.rc;
    } else if (got) {
        rc = receive(p[0], &h, result);
    }
    close(p[0]);
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
        ;
    if (WIFSIGNALED(st)) {
        status_message(err, errlen, "%s: libassimp crashed importing the asset (signal %d, %s); fix: re-export it",
                       path, WTERMSIG(st), strsignal(WTERMSIG(st)));
        return RC_ERR_PARSE;
    }
    if (got && h.rc == RC_OK && rc != RC_OK)
        status_message(err, errlen, "%s: the import's result was cut short (exit status %d); fix: free memory", path,
                       WIFEXITED(st) ? WEXITSTATUS(st) : -1);
    else if (!got)
        status_message(err, errlen, "%s: the import ended without a result (exit status %d); fix: re-export it", path,
                       WIFEXITED(st) ? WEXITSTATUS(st) : -1);
    return rc;
}

rc_status mesh_assimp_load(const char *path, const char *material_name, mesh_assimp_soup *out, char *err, size_t errlen)
{
    memset(out, 0, sizeof *out);
    rc_status rc = mas_child(path, material_name, mas_mesh_job, mas_mesh_receive, out, err, errlen);
    if (rc != RC_OK)
        mesh_assimp_soup_free(out);
    return rc;
}

rc_status mesh_assimp_material_load(const char *path, const char *material_name, mesh_assimp_material *out, char *err,
                                    size_t errlen)
{
    memset(out, 0, sizeof *out);
    return mas_child(path, material_name, mas_material_job, mas_material_receive, out, err, errlen);
}

/* --- the mapping rule -------------------------------------------------------------------- */

static vec3 mas_mix(vec3 a, vec3 b, float t) { return v3_add(v3_scale(a, 1.0f - t), v3_scale(b, t)); }

int mesh_assimp_material_apply(const mesh_assimp_material *a, material *m)
{
    int f0_set = 0;
    if (a->texture[0])
        snprintf(m->texture[MAT_TEX_DIFFUSE], sizeof m->texture[MAT_TEX_DIFFUSE], "%s", a->texture);
    if (a->pbr) {
        vec3 base = a->has_base ? a->base : a->has_diffuse ? a->diffuse : v3s(1.0f);
        float metal = fminf(fmaxf(a->metallic, 0.0f), 1.0f);
        float r = fminf(fmaxf(a->roughness, 0.0f), 1.0f);
        /* glTF: a dielectric's F0 is 0.04 (n = 1.5); a metal's is its base colour, and it has
         * no diffuse term. GGX alpha = r^2 is taken as the Beckmann m (the two lobes agree to
         * second order at small roughness; Walter et al. 2007, section 5.2). */
        vec3 f0 = mas_mix(v3s(0.04f), base, metal);
        m->albedo = v3_scale(base, 1.0f - metal);
        m->roughness = fmaxf(r * r, 1e-3f); /* m = 0 is a mirror: a delta lobe no rasterizer samples */
        m->ct.f0 = f0;
        f0_set = 1;
        /* Blinn-Phong exponent of the same lobe width: P = 2/m^2 - 2 (Walter et al. 2007, eq. 30). */
        float p = 2.0f / (m->roughness * m->roughness) - 2.0f;
        /* Below P = 1 (m > 0.82, a lobe wider than a cosine) Blinn-Phong turns into a flat
         * wash of colour over the whole surface, which the glTF lobe is not: no D3D highlight. */
        m->d3d.specular = p >= 1.0f ? f0 : v3s(0.0f);
        m->d3d.power = p >= 1.0f ? p : 0.0f;
    } else {
        if (a->has_diffuse)
            m->albedo = a->diffuse;
        if (a->has_specular)
            m->d3d.specular = a->specular;
        if (a->has_power)
            m->d3d.power = fmaxf(a->power, 0.0f);
        if (a->has_specular && a->has_power) {
            /* The Beckmann lobe of the same width as Blinn-Phong's P (the inverse of P = 2/m^2 - 2). */
            m->ct.f0 = a->specular;
            m->roughness = sqrtf(2.0f / (fmaxf(a->power, 0.0f) + 2.0f));
            f0_set = 1;
        }
    }
    if (a->has_emissive)
        m->d3d.emissive = a->emissive;
    if (a->has_ambient && !a->pbr)
        m->d3d.ambient = a->ambient;
    return f0_set;
}
