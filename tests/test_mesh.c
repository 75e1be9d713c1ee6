/* test_mesh.c - tessellation and OBJ/PLY loading.
 *
 * References are independent of mesh.c: points on the analytic surfaces, the exact area of the
 * inscribed polyhedron of a surface of revolution (a band of S isosceles trapezoids per ring
 * step), closed-form smooth areas and volumes for convergence, and hand-worked normals and
 * windings of the asymmetric fixtures. Runs from the repository root.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "mesh.h"
#include "scene_file.h"

#define MESHES "tests/fixtures/meshes/"
#define PI     3.14159265358979323846
/* Positions are float: 1e-6 relative is a few ulps at the sizes used here. */
#define FTOL   2e-6

static scene *one_object(object o)
{
    scene *s = malloc(sizeof *s);
    assert_non_null(s);
    scene_init(s);
    snprintf(s->path, sizeof s->path, "test.yaml");
    s->n_materials = 1;
    s->n_objects = 1;
    s->objects[0] = o;
    return s;
}

static void build_ok(const scene *s, mesh *m)
{
    char err[600] = "";
    rc_status rc = mesh_build(s, m, err, sizeof err);
    if (rc != RC_OK)
        print_error("%s\n", err);
    assert_int_equal(rc, RC_OK);
}

static dvec3 P(const mesh *m, int t, int c) { return dv3_from(m->pos[m->idx[3 * t + c]]); }
static dvec3 N(const mesh *m, int t, int c) { return dv3_from(m->nrm[m->idx[3 * t + c]]); }
static dvec3 cross_of(const mesh *m, int t)
{
    return dv3_cross(dv3_sub(P(m, t, 1), P(m, t, 0)), dv3_sub(P(m, t, 2), P(m, t, 0)));
}
static dvec3 centroid(const mesh *m, int t)
{
    return dv3_scale(dv3_add(dv3_add(P(m, t, 0), P(m, t, 1)), P(m, t, 2)), 1.0 / 3.0);
}

/* Invariants of every mesh: indices in range, finite positions, unit normals, no zero area. */
static void check_basic(const mesh *m)
{
    for (int i = 0; i < m->n_verts; i++) {
        assert_true(isfinite(m->pos[i].x) && isfinite(m->pos[i].y) && isfinite(m->pos[i].z));
        assert_float_equal(dv3_len(dv3_from(m->nrm[i])), 1.0, 1e-6);
    }
    for (int t = 0; t < m->n_tris; t++) {
        for (int c = 0; c < 3; c++)
            assert_true(m->idx[3 * t + c] < (uint32_t)m->n_verts);
        assert_true(dv3_len(cross_of(m, t)) > 0.0);
    }
}

static double total_area(const mesh *m)
{
    double a = 0;
    for (int t = 0; t < m->n_tris; t++)
        a += 0.5 * dv3_len(cross_of(m, t));
    return a;
}

/* Divergence theorem: a closed, outward-wound mesh gives its volume, inward gives minus it. */
static double signed_volume(const mesh *m)
{
    double v = 0;
    for (int t = 0; t < m->n_tris; t++)
        v += dv3_dot(P(m, t, 0), dv3_cross(P(m, t, 1), P(m, t, 2))) / 6.0;
    return v;
}

/* Inscribed polyhedron of a surface of revolution with S segments around the axis, through the
 * profile points (rho_j, y_j): each band is S trapezoids with parallel sides 2 rho sin(pi/S)
 * whose midpoints lie at rho cos(pi/S) from the axis. */
static double revolution_area(const double *rho, const double *y, int n_profile, int S)
{
    double a = 0, s = sin(PI / S), c = cos(PI / S);
    for (int j = 0; j + 1 < n_profile; j++) {
        double dr = (rho[j + 1] - rho[j]) * c, dy = y[j + 1] - y[j];
        a += S * s * (rho[j] + rho[j + 1]) * sqrt(dr * dr + dy * dy);
    }
    return a;
}

static double sphere_poly_area(double r, int S)
{
    int R = S / 2;
    double rho[1100], y[1100];
    for (int j = 0; j <= R; j++) {
        rho[j] = r * sin(PI * j / R);
        y[j] = r * cos(PI * j / R);
    }
    return revolution_area(rho, y, R + 1, S);
}

static void test_sphere(void **state)
{
    (void)state;
    object o;
    object_init(&o);
    o.shape = SHAPE_SPHERE;
    o.radius = 0.7f;
    o.center = v3(1, -2, 0.5f);
    o.rotate = v3(0.3f, -0.7f, 1.1f);
    o.tessellation = 32;
    scene *s = one_object(o);
    mesh m = {0};
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_verts, 2 * 32 + 33 * 15); /* pole vertices per triangle, a seam column */
    assert_int_equal(m.n_tris, 2 * 32 * 15);
    dvec3 c = dv3_from(o.center);
    for (int i = 0; i < m.n_verts; i++) {
        dvec3 d = dv3_sub(dv3_from(m.pos[i]), c);
        assert_float_equal(dv3_len(d), 0.7, FTOL * 3);
        assert_true(dv3_dot(dv3_norm(d), dv3_from(m.nrm[i])) > 1 - 1e-6); /* outward radial */
    }
    for (int t = 0; t < m.n_tris; t++) {
        assert_true(dv3_dot(cross_of(&m, t), dv3_sub(centroid(&m, t), c)) > 0); /* CCW outside */
        assert_int_equal(m.tri_object[t], 0);
    }
    /* Rotation does not change the inscribed polyhedron's area. */
    assert_float_equal(total_area(&m), sphere_poly_area(0.7, 32), 1e-5);
    assert_true(signed_volume(&m) > 0);
    mesh_free(&m);

    /* Convergence to 4 pi r^2: error falls ~4x per doubling. */
    double prev = 0;
    for (int S = 16; S <= 256; S *= 2) {
        s->objects[0].tessellation = S;
        build_ok(s, &m);
        double err = 4 * PI * 0.49 - total_area(&m);
        assert_true(err > 0); /* inscribed: always smaller */
        if (prev > 0)
            assert_true(prev / err > 3.5 && prev / err < 4.5);
        prev = err;
        mesh_free(&m);
    }
    /* Relative error ~ 0.83 (pi/S)^2 for this layout: 1.25e-4 at S = 256. */
    assert_true(prev / (4 * PI * 0.49) < 2e-4);
    free(s);
}

static void test_quad(void **state)
{
    (void)state;
    object o;
    object_init(&o);
    o.shape = SHAPE_QUAD;
    o.size = v3(4, 0, 3);
    o.center = v3(1, 2, 3);
    o.rotate = v3((float)(PI / 2), 0, 0); /* Rx(90): +Y -> +Z, (x, 0, z) -> (x, -z, 0) */
    scene *s = one_object(o);
    mesh m = {0};
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_tris, 2);
    assert_float_equal(total_area(&m), 12.0, 1e-5);
    for (int t = 0; t < 2; t++) {
        dvec3 n = dv3_norm(cross_of(&m, t));
        assert_float_equal(n.z, 1.0, 1e-6);
        for (int c = 0; c < 3; c++) {
            assert_float_equal(N(&m, t, c).z, 1.0, 1e-6);
            dvec3 p = P(&m, t, c);
            assert_float_equal(p.z, 3.0, 1e-6);
            assert_float_equal(fabs(p.x - 1), 2.0, 1e-6);
            assert_float_equal(fabs(p.y - 2), 1.5, 1e-6);
        }
    }
    mesh_free(&m);

    /* Euler order: X first, then Y. Rx(90) sends +Y to +Z, then Ry(90) sends +Z to +X.
     * (Y first would leave +Y, then Rx(90) gives +Z.) */
    s->objects[0].rotate = v3((float)(PI / 2), (float)(PI / 2), 0);
    build_ok(s, &m);
    assert_float_equal(dv3_norm(cross_of(&m, 0)).x, 1.0, 1e-6);
    assert_float_equal(N(&m, 0, 0).x, 1.0, 1e-6);
    mesh_free(&m);

    /* Unrotated: normal +Y and CCW seen from +Y. */
    s->objects[0].rotate = v3(0, 0, 0);
    build_ok(s, &m);
    assert_float_equal(dv3_norm(cross_of(&m, 0)).y, 1.0, 1e-6);
    assert_float_equal(dv3_norm(cross_of(&m, 1)).y, 1.0, 1e-6);
    mesh_free(&m);
    free(s);
}

static void test_box_sharp(void **state)
{
    (void)state;
    object o;
    object_init(&o);
    o.shape = SHAPE_BOX;
    o.size = v3(1, 2, 3);
    o.radius = 0;
    o.center = v3(-1, 0.5f, 2);
    scene *s = one_object(o);
    mesh m = {0};
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_tris, 12);
    assert_float_equal(total_area(&m), 2 * (2 + 6 + 3), 1e-5);
    assert_float_equal(signed_volume(&m), 6.0, 1e-5);
    for (int t = 0; t < 12; t++) {
        dvec3 n = dv3_norm(cross_of(&m, t));
        assert_true(dv3_dot(n, dv3_sub(centroid(&m, t), dv3_from(o.center))) > 0);
        for (int c = 0; c < 3; c++)
            assert_true(dv3_dot(N(&m, t, c), n) > 1 - 1e-6); /* face normals, not smoothed */
        /* an axis-aligned face normal */
        assert_float_equal(fabs(n.x) + fabs(n.y) + fabs(n.z), 1.0, 1e-6);
    }
    mesh_free(&m);
    free(s);
}

static void test_box_rounded(void **state)
{
    (void)state;
    const double r = 0.25, A = 0.5, B = 1.5, C = 2.5; /* inner extents: size - 2r */
    object o;
    object_init(&o);
    o.shape = SHAPE_BOX;
    o.size = v3(1, 2, 3);
    o.radius = (float)r;
    o.center = v3(0.25f, -1, 0.5f);
    o.rotate = v3(0.2f, 0.4f, -0.3f);
    scene *s = one_object(o);
    mesh m = {0};
    double smooth_area = 2 * (A * B + B * C + C * A) + 2 * PI * r * (A + B + C) + 4 * PI * r * r;
    double smooth_vol =
        A * B * C + r * 2 * (A * B + B * C + C * A) + PI * r * r * (A + B + C) + 4.0 / 3.0 * PI * r * r * r;
    double prev = 0;
    for (int T = 2; T <= 32; T *= 2) {
        s->objects[0].tessellation = T;
        build_ok(s, &m);
        check_basic(&m);
        double area = total_area(&m);
        /* Faces are exact; an edge strip is T chords of 2 r sin(pi/(4T)); the corners form an
         * inscribed polyhedral sphere, so less than 4 pi r^2. */
        double flat = 2 * (A * B + B * C + C * A);
        double edges = 4 * (A + B + C) * T * 2 * r * sin(PI / (4 * T));
        double corners = area - flat - edges;
        assert_true(corners < 4 * PI * r * r);
        assert_true(corners > 4 * PI * r * r * (1 - 2.0 / (T * T)));
        double err = smooth_area - area;
        assert_true(err > 0);
        if (prev > 0)
            assert_true(prev / err > 3.0 && prev / err < 4.6);
        prev = err;
        double vol = signed_volume(&m);
        assert_true(vol > 0 && vol < smooth_vol);
        assert_true((smooth_vol - vol) / smooth_vol < 1.0 / (T * T));

        /* Every vertex at distance r from the inner box, normal pointing away from it.
         * Work in object space by undoing the center and rotation. */
        double cx = cos(0.2), sx = sin(0.2), cy = cos(0.4), sy = sin(0.4), cz = cos(-0.3), sz = sin(-0.3);
        for (int i = 0; i < m.n_verts; i++) {
            dvec3 p = dv3_sub(dv3_from(m.pos[i]), dv3_from(o.center)), n = dv3_from(m.nrm[i]);
            dvec3 *vs[2] = {&p, &n};
            for (int k = 0; k < 2; k++) { /* inverse: Rz^-1, then Ry^-1, then Rx^-1 */
                dvec3 v = *vs[k];
                v = dv3(cz * v.x + sz * v.y, -sz * v.x + cz * v.y, v.z);
                v = dv3(cy * v.x - sy * v.z, v.y, sy * v.x + cy * v.z);
                v = dv3(v.x, cx * v.y + sx * v.z, -sx * v.y + cx * v.z);
                *vs[k] = v;
            }
            dvec3 q =
                dv3(fmax(-A / 2, fmin(A / 2, p.x)), fmax(-B / 2, fmin(B / 2, p.y)), fmax(-C / 2, fmin(C / 2, p.z)));
            dvec3 d = dv3_sub(p, q);
            assert_float_equal(dv3_len(d), r, 1e-5);
            assert_true(dv3_dot(dv3_norm(d), n) > 1 - 1e-5);
        }
        for (int t = 0; t < m.n_tris; t++)
            assert_true(dv3_dot(cross_of(&m, t), dv3_sub(centroid(&m, t), dv3_from(o.center))) > 0);
        mesh_free(&m);
    }
    /* radius = half the smallest size: still closed, the faces of that axis vanish. */
    s->objects[0].radius = 0.5f;
    s->objects[0].tessellation = 8;
    build_ok(s, &m);
    check_basic(&m);
    assert_true(signed_volume(&m) > 0);
    mesh_free(&m);
    free(s);
}

static void test_torus(void **state)
{
    (void)state;
    const double R = 1.0, r = 0.25;
    object o;
    object_init(&o);
    o.shape = SHAPE_TORUS;
    o.major = (float)R;
    o.radius = (float)r;
    o.center = v3(0.5f, 0.25f, -1);
    scene *s = one_object(o);
    mesh m = {0};
    double prev = 0;
    for (int S = 12; S <= 192; S *= 2) {
        s->objects[0].tessellation = S;
        build_ok(s, &m);
        check_basic(&m);
        int nv = S / 2;
        assert_int_equal(m.n_tris, 2 * S * nv);
        double rho[200], y[200];
        for (int j = 0; j <= nv; j++) {
            rho[j] = R + r * cos(2 * PI * j / nv);
            y[j] = r * sin(2 * PI * j / nv);
        }
        double area = total_area(&m);
        assert_float_equal(area, revolution_area(rho, y, nv + 1, S), 1e-5 * area);
        double err = 4 * PI * PI * R * r - area;
        assert_true(err > 0);
        if (prev > 0)
            assert_true(prev / err > 3.5 && prev / err < 4.5);
        prev = err;
        /* Vertices on the tube, normals away from the ring circle, windings outward. */
        dvec3 c = dv3_from(o.center);
        for (int i = 0; i < m.n_verts; i++) {
            dvec3 p = dv3_sub(dv3_from(m.pos[i]), c);
            dvec3 ring = dv3_scale(dv3_norm(dv3(p.x, 0, p.z)), R);
            dvec3 d = dv3_sub(p, ring);
            assert_float_equal(dv3_len(d), r, 1e-6);
            assert_true(dv3_dot(dv3_norm(d), dv3_from(m.nrm[i])) > 1 - 1e-6);
        }
        for (int t = 0; t < m.n_tris; t++) {
            dvec3 p = dv3_sub(centroid(&m, t), c);
            dvec3 ring = dv3_scale(dv3_norm(dv3(p.x, 0, p.z)), R);
            assert_true(dv3_dot(cross_of(&m, t), dv3_sub(p, ring)) > 0);
        }
        assert_true(signed_volume(&m) > 0);
        mesh_free(&m);
    }
    assert_true(prev / (4 * PI * PI * R * r) < 1e-3);
    free(s);
}

static scene *mesh_scene(const char *path, vec3 center, vec3 rotate)
{
    object o;
    object_init(&o);
    o.shape = SHAPE_MESH;
    o.center = center;
    o.rotate = rotate;
    snprintf(o.path, sizeof o.path, "%s", path);
    return one_object(o);
}

static void assert_dv3(dvec3 a, double x, double y, double z, double tol)
{
    assert_float_equal(a.x, x, tol);
    assert_float_equal(a.y, y, tol);
    assert_float_equal(a.z, z, tol);
}

/* The tetrahedron (0,0,0), (2,0,0), (0,3,0), (0,0,1), faces in file order with their outward
 * normals; shared by tetra.obj and tetra_ascii.ply. */
static const int tetra_faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
static const double tetra_v[4][3] = {{0, 0, 0}, {2, 0, 0}, {0, 3, 0}, {0, 0, 1}};
/* cross products (b - a) x (c - a) worked by hand: bottom, y = 0, x = 0, slanted */
static const double tetra_cross[4][3] = {{0, 0, -6}, {0, -2, 0}, {-3, 0, 0}, {3, 2, 6}};
/* Area-weighted vertex normals: sums of the cross products of each vertex's faces. */
static const double tetra_n[4][3] = {{-3 / 7.0, -2 / 7.0, -6 / 7.0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};

/* n_verts: 4 when shared (one normal per position); tetra.obj's second face gives its corners
 * texture coordinates, so they are vertices of their own there (7). */
static void check_tetra(const mesh *m, dvec3 shift, int n_verts)
{
    assert_int_equal(m->n_tris, 4);
    assert_int_equal(m->n_verts, n_verts);
    for (int t = 0; t < 4; t++) {
        for (int c = 0; c < 3; c++) {
            const double *v = tetra_v[tetra_faces[t][c]], *n = tetra_n[tetra_faces[t][c]];
            assert_dv3(P(m, t, c), v[0] + shift.x, v[1] + shift.y, v[2] + shift.z, 1e-6);
            assert_dv3(N(m, t, c), n[0], n[1], n[2], 2e-6);
        }
        assert_dv3(cross_of(m, t), tetra_cross[t][0], tetra_cross[t][1], tetra_cross[t][2], 1e-5);
    }
    assert_float_equal(signed_volume(m), 1.0, 1e-5); /* 2*3*1/6, positive: outward */
}

static void test_obj_tetra(void **state)
{
    (void)state;
    scene *s = mesh_scene(MESHES "tetra.obj", v3(10, -1, 0.5f), v3(0, 0, 0));
    mesh m = {0};
    build_ok(s, &m);
    check_basic(&m);
    check_tetra(&m, dv3(10, -1, 0.5), 7);
    /* The v/vt face's corners carry vt 1..3; the others none, so (0, 0). */
    for (int c = 0; c < 3; c++) {
        uint32_t i = m.idx[3 * 1 + c];
        const float want[3][2] = {{0, 0}, {1, 0}, {0, 1}};
        assert_float_equal(m.uv[2 * i], want[c][0], 0);
        assert_float_equal(m.uv[2 * i + 1], want[c][1], 0);
    }
    mesh_free(&m);
    /* Rz(90): (2,0,0) -> (0,2,0), its normal +X -> +Y. */
    s->objects[0].rotate = v3(0, 0, (float)(PI / 2));
    s->objects[0].center = v3(0, 0, 0);
    build_ok(s, &m);
    assert_dv3(P(&m, 1, 1), 0, 2, 0, 1e-6);
    assert_dv3(N(&m, 1, 1), 0, 1, 0, 1e-6);
    assert_float_equal(signed_volume(&m), 1.0, 1e-5);
    mesh_free(&m);
    free(s);
}

static void test_obj_pentagon(void **state)
{
    (void)state;
    scene *s = mesh_scene(MESHES "pentagon.obj", v3(0, 0, 0), v3(0, 0, 0));
    mesh m = {0};
    static const double v[5][2] = {{0, 0}, {2, 0}, {3, 1}, {1.5, 2.5}, {-0.5, 1}};
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_tris, 3);
    assert_int_equal(m.n_verts, 5);
    for (int t = 0; t < 3; t++) { /* fan: (1, t+2, t+3) */
        int corner[3] = {0, t + 1, t + 2};
        for (int c = 0; c < 3; c++) {
            assert_dv3(P(&m, t, c), v[corner[c]][0], v[corner[c]][1], 1, 1e-6);
            assert_dv3(N(&m, t, c), 0, 0, 1, 1e-6); /* vn 0 0 2, normalised */
        }
        assert_true(cross_of(&m, t).z > 0);
    }
    /* Shoelace area of the pentagon: (0 + 2 + 6 + 2.75 + 0)/2 = 5.375 */
    assert_float_equal(total_area(&m), 5.375, 1e-5);
    mesh_free(&m);
    free(s);
}

static void test_ply_ascii(void **state)
{
    (void)state;
    scene *s = mesh_scene(MESHES "tetra_ascii.ply", v3(0, 0, 0), v3(0, 0, 0));
    mesh m = {0};
    build_ok(s, &m);
    check_basic(&m);
    check_tetra(&m, dv3(0, 0, 0), 4); /* the file's normals are the area-weighted ones, rounded */
    mesh_free(&m);
    free(s);
}

static void test_ply_binary(void **state)
{
    (void)state;
    scene *s = mesh_scene(MESHES "pyramid_binary.ply", v3(0, 0, 0), v3(0, 0, 0));
    mesh m = {0};
    static const double v[5][3] = {{0, 0, 0}, {2, 0, 0}, {2, 0, 1}, {0, 0, 1}, {0.5, 1.5, 0.25}};
    static const int tri[6][3] = {{0, 1, 2}, {0, 2, 3}, {0, 4, 1}, {1, 4, 2}, {2, 4, 3}, {3, 4, 0}};
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_tris, 6);
    assert_int_equal(m.n_verts, 5);
    dvec3 inside = dv3(0.9, 0.3, 0.45); /* mean of the vertices */
    for (int t = 0; t < 6; t++) {
        for (int c = 0; c < 3; c++)
            assert_dv3(P(&m, t, c), v[tri[t][c]][0], v[tri[t][c]][1], v[tri[t][c]][2], 1e-12);
        assert_true(dv3_dot(cross_of(&m, t), dv3_sub(centroid(&m, t), inside)) > 0);
    }
    assert_float_equal(signed_volume(&m), 2.0 * 1.5 / 3.0, 1e-5); /* base 2 x 1, height 1.5 */
    mesh_free(&m);
    free(s);
}

static void expect_mesh_error(const char *file, rc_status want, const char *where)
{
    char path[256], err[600] = "";
    snprintf(path, sizeof path, MESHES "%s", file);
    scene *s = mesh_scene(path, v3(0, 0, 0), v3(0, 0, 0));
    /* A sphere first, so a failing mesh must leave the earlier triangles as they were. */
    s->objects[1] = s->objects[0];
    object_init(&s->objects[0]);
    s->n_objects = 2;
    mesh m = {0};
    assert_int_equal(mesh_add_object(s, 0, &m, err, sizeof err), RC_OK);
    int nv = m.n_verts, nt = m.n_tris;
    rc_status rc = mesh_add_object(s, 1, &m, err, sizeof err);
    if (rc != want || !strstr(err, where) || !strstr(err, "fix"))
        fail_msg("%s: rc %d (want %d): %s", file, rc, want, err);
    assert_int_equal(m.n_verts, nv);
    assert_int_equal(m.n_tris, nt);
    mesh_free(&m);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), want);
    assert_null(m.pos); /* freed on failure */
    free(s);
}

static void test_mesh_errors(void **state)
{
    (void)state;
    expect_mesh_error("all_degenerate.obj", RC_ERR_RANGE, "all_degenerate.obj: all 2 triangles have zero area");
    expect_mesh_error("no_faces.obj", RC_ERR_RANGE, "no_faces.obj: no faces");
    expect_mesh_error("bad_index.obj", RC_ERR_RANGE, "bad_index.obj:4: corner '4': vertex index out of range");
    expect_mesh_error("truncated.ply", RC_ERR_PARSE, "truncated.ply: PLY data ends early");
    expect_mesh_error("bigendian.ply", RC_ERR_PARSE, "bigendian.ply:2: PLY format");
    expect_mesh_error("missing.obj", RC_ERR_IO, "missing.obj");
    /* Geometry a scene file would refuse, set in code. */
    object o;
    object_init(&o);
    o.radius = -1;
    scene *s = one_object(o);
    mesh m = {0};
    char err[300];
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "objects[0] (sphere)"));
    free(s);
}

/* Writes bytes to a temporary mesh file named by suffix; returns its path in a static buffer. */
static const char *temp_mesh(const char *suffix, const void *bytes, size_t n)
{
    static char path[128];
    snprintf(path, sizeof path, "/tmp/reflcheck_lenient_%ld%s", (long)getpid(), suffix);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(bytes, 1, n, f), n);
    fclose(f);
    return path;
}

/* Builds the mesh file of `text` (written under suffix) as one object; returns the status and
 * leaves the message in err. */
static rc_status build_text(const char *suffix, const char *text, char *err, size_t errlen)
{
    scene *s = mesh_scene(temp_mesh(suffix, text, strlen(text)), v3(0, 0, 0), v3(0, 0, 0));
    mesh m = {0};
    err[0] = '\0';
    rc_status rc = mesh_build(s, &m, err, errlen);
    mesh_free(&m);
    free(s);
    return rc;
}

/* An ascii PLY value of an integer type must fit the type (PLY's ranges: char -128..127, uchar
 * 0..255, short -32768..32767, ushort 0..65535, int -2^31..2^31-1, uint 0..2^32-1): the bounds
 * are read, one past them is refused with the line, the element, the property and the value
 * as written. A uchar colour of 300 used to be read as 300/255 = 1.18, -5 refused as "colour
 * -0.0196078". */
static void test_ply_integer_ranges(void **state)
{
    (void)state;
    static const struct {
        const char *type, *lo, *hi, *below, *above;
    } t[] = {
        {"char", "-128", "127", "-129", "128"},
        {"uchar", "0", "255", "-1", "256"},
        {"short", "-32768", "32767", "-32769", "32768"},
        {"ushort", "0", "65535", "-1", "65536"},
        {"int", "-2147483648", "2147483647", "-2147483649", "2147483648"},
        {"uint", "0", "4294967295", "-1", "4294967296"},
        {"int8", "-128", "127", "-129", "128"},
        {"uint32", "0", "4294967295", "-1", "4294967296"},
    };
    char text[600], err[600];
    for (size_t i = 0; i < sizeof t / sizeof *t; i++) {
        const char *vals[4] = {t[i].lo, t[i].hi, t[i].below, t[i].above};
        for (int k = 0; k < 4; k++) {
            /* The value is vertex 1's on line 12. */
            snprintf(text, sizeof text,
                     "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nproperty %s flags\nelement face 1\nproperty list uchar int "
                     "vertex_indices\nend_header\n0 0 0 0\n1 0 0 %s\n0 1 0 0\n3 0 1 2\n",
                     t[i].type, vals[k]);
            rc_status rc = build_text(".ply", text, err, sizeof err);
            char want[200];
            snprintf(want, sizeof want, ":12: vertex 1, property flags: '%s' is outside the range of its type",
                     vals[k]);
            if (k < 2 ? rc != RC_OK : (rc != RC_ERR_RANGE || !strstr(err, want) || !strstr(err, "fix")))
                fail_msg("%s %s: rc %d: %s", t[i].type, vals[k], rc, err);
        }
    }
    /* The colours of the issue, a list count beyond its type, and a fraction for an integer. */
    static const char *const head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                    "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar "
                                    "blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    static const struct {
        const char *data, *want;
    } bad[] = {
        {"0 0 0 0 0 0\n1 0 0 300 0 0\n0 1 0 0 0 0\n3 0 1 2\n", ":14: vertex 1, property red: '300' is outside"},
        {"0 0 0 0 0 0\n1 0 0 0 -5 0\n0 1 0 0 0 0\n3 0 1 2\n", ":14: vertex 1, property green: '-5' is outside"},
        {"0 0 0 0 0 0\n1 0 0 0 0 0\n0 1 0 0 0 0\n256 0 1 2\n",
         ":16: face 0, list length of vertex_indices: '256' is outside the range of its type uchar"},
        {"0 0 0 0 0 0\n1 0 0 0 0 0\n0 1 0 0 0 0\n3 0 1.5 2\n", ":16: face 0, property vertex_indices: '1.5' is not a "
                                                               "whole number, but its type is int"},
        {"0 0 0 0 0 0\n1 0 0 0 0 nan\n0 1 0 0 0 0\n3 0 1 2\n", ":14: vertex 1, property blue: 'nan' is not a whole"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        snprintf(text, sizeof text, "%s%s", head, bad[i].data);
        rc_status rc = build_text(".ply", text, err, sizeof err);
        if (rc != RC_ERR_RANGE || !strstr(err, bad[i].want) || !strstr(err, "fix"))
            fail_msg("case %zu: rc %d: %s", i, rc, err);
    }
    snprintf(text, sizeof text, "%s%s", head, "0 0 0 0 0 0\n1 0 0 255 128 0\n0 1 0 0 0 0\n3 0 1 2\n");
    assert_int_equal(build_text(".ply", text, err, sizeof err), RC_OK);
}

/* OBJ indices beyond long (strtol saturates) and LONG_MIN (whose negation overflows) are
 * refused as out of range, quoting the corner as written. */
static void test_obj_huge_indices(void **state)
{
    (void)state;
    static const char *const corners[] = {"99999999999999999999",     "-9223372036854775808", "1/99999999999999999999",
                                          "1//-99999999999999999999", "2147483648",           "-2147483649"};
    char text[300], err[600], want[120];
    for (size_t i = 0; i < sizeof corners / sizeof *corners; i++) {
        snprintf(text, sizeof text, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1 2 %s\n", corners[i]);
        snprintf(want, sizeof want, ":6: corner '%s':", corners[i]);
        rc_status rc = build_text(".obj", text, err, sizeof err);
        if (rc != RC_ERR_RANGE || !strstr(err, want) || !strstr(err, "out of range"))
            fail_msg("corner %s: rc %d: %s", corners[i], rc, err);
    }
}

/* Lenient where renderers are: zero-area triangles are left out and counted, zero or
 * non-finite file normals are recomputed from the faces and counted; the normals expected are
 * worked by hand in the fixtures' comments. */
static void test_mesh_lenient(void **state)
{
    (void)state;
    char note[512];
    mesh m = {0};
    /* degenerate.obj: face 1 2 4 is proper, face 1 2 3 (line 7) collinear. */
    scene *s = mesh_scene(MESHES "degenerate.obj", v3(0, 0, 0), v3(0, 0, 0));
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_tris, 1);
    assert_int_equal(m.dropped[0], 1);
    assert_int_equal(m.recomputed[0], 0);
    assert_int_equal(mesh_repair_note(s, &m, note, sizeof note), 1);
    assert_non_null(strstr(note, "objects[0] (" MESHES "degenerate.obj): 1 zero-area triangle left out"));
    mesh_free(&m);
    free(s);

    s = mesh_scene(MESHES "zero_normal.obj", v3(0, 0, 0), v3(0, 0, 0));
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_tris, 3);
    assert_int_equal(m.dropped[0], 0);
    assert_int_equal(m.recomputed[0], 2);
    int seen = 0;
    for (int t = 0; t < m.n_tris; t++)
        for (int c = 0; c < 3; c++) {
            dvec3 p = P(&m, t, c), n = N(&m, t, c);
            if (p.x == 1 && p.y == 0 && p.z == 0) {
                assert_dv3(n, 0, sqrt(0.5), sqrt(0.5), 1e-6);
                seen |= 1;
            } else if (p.x == 0 && p.y == 1 && p.z == 0) {
                assert_dv3(n, 0, 0, 1, 1e-6);
                seen |= 2;
            } else {
                assert_dv3(n, 0, 0, 1, 1e-6); /* the file's own normal */
            }
        }
    assert_int_equal(seen, 3);
    int d, r;
    mesh_repair_totals(&m, &d, &r);
    assert_int_equal(d, 0);
    assert_int_equal(r, 2);
    assert_int_equal(mesh_repair_note(s, &m, note, sizeof note), 1);
    assert_non_null(strstr(note, "2 zero or non-finite normals recomputed from the faces"));
    mesh_free(&m);
    free(s);

    s = mesh_scene(MESHES "zero_normal.ply", v3(0, 0, 0), v3(0, 0, 0));
    build_ok(s, &m);
    check_basic(&m);
    assert_int_equal(m.n_tris, 1);
    assert_int_equal(m.recomputed[0], 1);
    for (int c = 0; c < 3; c++)
        assert_dv3(N(&m, 0, c), 0, 0, 1, 1e-6);
    mesh_free(&m);
    free(s);

    /* A UTF-8 byte-order mark is skipped; UTF-16 is refused by name. */
    static const char bom8[] = "\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    s = mesh_scene(temp_mesh(".obj", bom8, sizeof bom8 - 1), v3(0, 0, 0), v3(0, 0, 0));
    build_ok(s, &m);
    assert_int_equal(m.n_tris, 1);
    mesh_free(&m);
    static const char bom16[] = "\xFE\xFF\0v\0 \0001";
    temp_mesh(".obj", bom16, sizeof bom16 - 1);
    char err[600];
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, ":1: UTF-16 or UTF-32 text"));
    /* A bad number is named. */
    static const char badnum[] = "v 0 0 0\nv 1 2. 3.1+e2\n";
    temp_mesh(".obj", badnum, sizeof badnum - 1);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_ERR_PARSE);
    assert_non_null(strstr(err, ":2: bad vertex: '3.1+e2' is not a number"));
    remove(s->objects[0].path);
    free(s);
}

/* Real meshes no one here wrote (Debian's assimp-testmodels, installed by ops/deps.sh): the
 * three the reader used to refuse although every renderer takes them. The counts were worked
 * out apart from mesh.c, by a Python fan triangulation of each file in double precision
 * (docs/meshes.md); the spider's one zero normal serves only zero-area triangles. */
static void test_assimp_models(void **state)
{
    (void)state;
    static const struct {
        const char *file;
        int tris, dropped, recomputed;
    } want[] = {{"OBJ/regr01.obj", 2706, 4, 0}, {"OBJ/box_longline.obj", 478, 466, 0}, {"OBJ/spider.obj", 1312, 56, 0}};
    for (size_t i = 0; i < sizeof want / sizeof *want; i++) {
        char path[256];
        snprintf(path, sizeof path, "/usr/share/assimp/models/%s", want[i].file);
        if (access(path, R_OK) != 0)
            fail_msg("%s missing: install it with apt-get install assimp-testmodels (ops/deps.sh does)", path);
        scene *s = mesh_scene(path, v3(0, 0, 0), v3(0, 0, 0));
        mesh m = {0};
        build_ok(s, &m);
        check_basic(&m);
        assert_int_equal(m.n_tris, want[i].tris);
        assert_int_equal(m.dropped[0], want[i].dropped);
        assert_int_equal(m.recomputed[0], want[i].recomputed);
        mesh_free(&m);
        free(s);
    }
}

/* scale [2, 1, 0.5] then rotate 90 degrees about Z then translate: the unit sphere becomes the
 * ellipsoid (qy/2)^2 + qx^2 + (qz/0.5)^2 = 1 around the centre (the X axis, scaled 2, turns into
 * +Y), whose outward normal is the gradient (qx, qy/4, qz/0.25) normalised: an analytic
 * reference that a wrong order (rotate before scale) or a normal transformed by the scale
 * itself instead of its inverse would miss. The D3D length of that normal, 1/|S R^T n|, is
 * checked against the unnormalised R S^-1 n_object worked from the sphere's own normal. */
static void test_scale(void **state)
{
    (void)state;
    object o;
    object_init(&o);
    o.radius = 1.0f;
    o.tessellation = 24;
    o.scale = v3(2.0f, 1.0f, 0.5f);
    o.rotate = v3(0.0f, 0.0f, (float)(PI / 2));
    o.center = v3(0.25f, -0.5f, 1.0f);
    scene *s = one_object(o);
    mesh m = {0};
    build_ok(s, &m);
    check_basic(&m);
    mesh_normal_length L;
    mesh_normal_length_make(&s->objects[0], &L);
    assert_false(L.unit);
    for (int i = 0; i < m.n_verts; i++) {
        dvec3 q = dv3_sub(dv3_from(m.pos[i]), dv3(0.25, -0.5, 1.0));
        assert_float_equal(q.y / 2 * q.y / 2 + q.x * q.x + q.z / 0.5 * q.z / 0.5, 1.0, 1e-5);
        dvec3 g = dv3_norm(dv3(q.x, q.y / 4, q.z / 0.25));
        assert_dv3(dv3_from(m.nrm[i]), g.x, g.y, g.z, 1e-5);
        /* The object-space point (and unit normal) of the sphere: undo translate, rotate, scale. */
        dvec3 p = dv3(q.y / 2, -q.x / 1, q.z / 0.5);
        /* D3D: R S^-1 p, R the 90 degree turn (x, y, z) -> (-y, x, z). */
        dvec3 d3d = dv3(-(p.y / 1), p.x / 2, p.z / 0.5);
        assert_float_equal(mesh_normal_length_of(&L, m.nrm[i]), dv3_len(d3d), 1e-5 * dv3_len(d3d));
    }
    mesh_free(&m);
    free(s);

    /* The scene file's scalar form; an unscaled object's D3D length is exactly 1. */
    const char *yaml = "image: {width: 8, height: 8}\ncamera: {eye: [0, 0, 5], target: [0, 0, 0], hfov: 40}\n"
                       "materials: {m: {}}\nobjects:\n  - {shape: quad, size: [1, 1], scale: 3, material: m}\n"
                       "  - {shape: quad, size: [1, 1], material: m}\n";
    char path[128], err[600];
    snprintf(path, sizeof path, "/tmp/reflcheck_scale_%ld.yaml", (long)getpid());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(yaml, f);
    fclose(f);
    s = malloc(sizeof *s);
    assert_int_equal(scene_file_load(path, s, err, sizeof err), RC_OK);
    remove(path);
    assert_float_equal(s->objects[0].scale.x, 3.0, 0);
    assert_float_equal(s->objects[0].scale.z, 3.0, 0);
    build_ok(s, &m);
    assert_float_equal(total_area(&m), 9.0 + 1.0, 1e-5);
    mesh_normal_length_make(&s->objects[1], &L);
    assert_true(L.unit);
    assert_true(mesh_normal_length_of(&L, v3(0.6f, 0.8f, 0.0f)) == 1.0f);
    mesh_normal_length_make(&s->objects[0], &L);
    assert_float_equal(mesh_normal_length_of(&L, v3(0.0f, 1.0f, 0.0f)), 1.0 / 3.0, 1e-7);
    mesh_free(&m);
    free(s);
}

/* mesh_build on path in a child: exit 0 when it returns RC_ERR_RANGE with want in the
 * message. The alarm turns a blocking open (FIFO) into a failure instead of a hang; the
 * address-space cap turns an unbounded read (/dev/zero) into one instead of the OOM killer
 * (not under ASan, which reserves terabytes of shadow address space). */
static int build_in_child(const char *path, const char *want)
{
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        alarm(20);
#ifndef __SANITIZE_ADDRESS__
        struct rlimit rl = {.rlim_cur = (rlim_t)3 << 30, .rlim_max = (rlim_t)3 << 30};
        setrlimit(RLIMIT_AS, &rl);
#endif
        scene *s = mesh_scene(path, v3(0, 0, 0), v3(0, 0, 0));
        mesh m = {0};
        char err[600] = "";
        rc_status rc = mesh_build(s, &m, err, sizeof err);
        if (rc != RC_ERR_RANGE || strstr(err, want) == NULL || strstr(err, "objects[0]") == NULL) {
            fprintf(stderr, "%s: rc %d: %s\n", path, rc, err);
            _exit(1);
        }
        _exit(0);
    }
    int ws = 0;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    return WIFEXITED(ws) ? WEXITSTATUS(ws) : 128 + (WIFSIGNALED(ws) ? WTERMSIG(ws) : 0);
}

/* A mesh path to /dev/zero used to be read without bound (24 GB, the OOM killer), a FIFO
 * blocked forever and a 2 GB file was read whole before being refused; now all three are
 * refused by kind or size before the first byte, even when mesh_build is called directly. */
static void test_mesh_file_limits(void **state)
{
    (void)state;
    char dir[64], zero[128], fifo[128], big[128];
    snprintf(dir, sizeof dir, "/tmp/reflcheck-mesh-%ld", (long)getpid());
    assert_int_equal(mkdir(dir, 0755), 0);
    snprintf(zero, sizeof zero, "%s/zero.obj", dir);
    snprintf(fifo, sizeof fifo, "%s/fifo.ply", dir);
    snprintf(big, sizeof big, "%s/big.obj", dir);
    assert_int_equal(symlink("/dev/zero", zero), 0);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    int fd = open(big, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    assert_true(fd >= 0);
    assert_int_equal(ftruncate(fd, (off_t)2 << 30), 0); /* sparse: no data blocks */
    close(fd);
    assert_int_equal(build_in_child(zero, "not a regular file (a character device)"), 0);
    assert_int_equal(build_in_child(fifo, "not a regular file (a FIFO)"), 0);
    assert_int_equal(build_in_child(big, "2147483648 bytes is over the limit of 1073741824 bytes"), 0);
    unlink(zero);
    unlink(fifo);
    unlink(big);
    rmdir(dir);
}

static void test_scene_files(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s);
    char err[600] = "";
    mesh m = {0};
    assert_int_equal(scene_file_load("tests/fixtures/scenes/good_full.yaml", s, err, sizeof err), RC_OK);
    build_ok(s, &m);
    check_basic(&m);
    int count[SCENE_MAX_OBJECTS] = {0}, last = 0;
    for (int t = 0; t < m.n_tris; t++) {
        assert_true(m.tri_object[t] >= last); /* objects in order */
        last = m.tri_object[t];
        count[last]++;
    }
    assert_int_equal(count[0], 2 * 48 * 23); /* sphere 48 */
    assert_int_equal(count[1], 2);           /* quad */
    assert_int_equal(count[2], 12 + 24 * 8 + 8 * 64);
    assert_int_equal(count[3], 2 * 24 * 12); /* torus 24 x 12 */
    assert_int_equal(count[4], 4);           /* tetra.obj */
    mesh_free(&m);

    assert_int_equal(scene_file_load("tests/fixtures/scenes/mesh_degenerate.yaml", s, err, sizeof err), RC_OK);
    assert_int_equal(mesh_build(s, &m, err, sizeof err), RC_ERR_RANGE);
    assert_non_null(strstr(err, "meshes/all_degenerate.obj: all 2 triangles have zero area"));
    free(s);
}

/* Every prefix and random byte edits of each mesh fixture: any status, never a crash (the
 * sanitizer build makes out-of-bounds reads fail), a message naming the file on failure. */
static void test_mesh_mutations(void **state)
{
    (void)state;
    static const char *const files[] = {"tetra.obj", "pentagon.obj", "tetra_ascii.ply", "pyramid_binary.ply"};
    static const char pool[] = "0123456789-+.eE /\n\r\tvnf#";
    srand(4242);
    for (size_t fi = 0; fi < sizeof files / sizeof *files; fi++) {
        char src[256], dst[256], err[600];
        snprintf(src, sizeof src, MESHES "%s", files[fi]);
        snprintf(dst, sizeof dst, "/tmp/reflcheck_mesh_%ld%s", (long)getpid(), strrchr(files[fi], '.'));
        FILE *f = fopen(src, "rb");
        assert_non_null(f);
        unsigned char orig[4096], buf[4096];
        size_t len = fread(orig, 1, sizeof orig, f);
        fclose(f);
        scene *s = mesh_scene(dst, v3(0, 0, 0), v3(0, 0, 0));
        for (int it = 0; it < (int)len + 600; it++) {
            size_t n = len;
            memcpy(buf, orig, len);
            if (it < (int)len) {
                n = (size_t)it; /* truncation */
            } else {
                for (int e = 0; e < 1 + rand() % 3; e++)
                    buf[(size_t)rand() % len] = rand() % 3 ? (unsigned char)pool[rand() % (int)(sizeof pool - 1)]
                                                           : (unsigned char)(rand() & 0xff);
            }
            f = fopen(dst, "wb");
            assert_non_null(f);
            fwrite(buf, 1, n, f);
            fclose(f);
            mesh m = {0};
            err[0] = '\0';
            rc_status rc = mesh_build(s, &m, err, sizeof err);
            if (rc == RC_OK)
                check_basic(&m);
            else if (!strstr(err, dst) || strchr(err, '\n'))
                fail_msg("%s mutant %d: rc %d, message '%s'", files[fi], it, rc, err);
            mesh_free(&m);
        }
        remove(dst);
        free(s);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sphere),
        cmocka_unit_test(test_quad),
        cmocka_unit_test(test_box_sharp),
        cmocka_unit_test(test_box_rounded),
        cmocka_unit_test(test_torus),
        cmocka_unit_test(test_obj_tetra),
        cmocka_unit_test(test_obj_pentagon),
        cmocka_unit_test(test_ply_ascii),
        cmocka_unit_test(test_ply_binary),
        cmocka_unit_test(test_mesh_errors),
        cmocka_unit_test(test_ply_integer_ranges),
        cmocka_unit_test(test_obj_huge_indices),
        cmocka_unit_test(test_mesh_lenient),
        cmocka_unit_test(test_scale),
        cmocka_unit_test(test_assimp_models),
        cmocka_unit_test(test_mesh_file_limits),
        cmocka_unit_test(test_scene_files),
        cmocka_unit_test(test_mesh_mutations),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
