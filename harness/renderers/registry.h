/* registry.h - the one table of renderers: one row each, as Lua's linit.c registers libraries.
 *
 * Usage:
 *   int i = registry_find("povray");                 -1 if no such renderer
 *   const renderer_row *row = registry_row(i);
 *   row->render(&job, &result);                      the render entry (renderer.h)
 *   for (int i = 0; i < registry_count(); i++) ... registry_row(i)->name ...
 *   registry_list(buf, sizeof buf);                  "raster, povray or cycles", for messages
 * A renderer's index is its row; scene files, job records and run folders hold its name. Nothing
 * outside this table and the renderer's own folder names a renderer: adding one is a folder
 * harness/renderers/NAME/ with its entry, and one row in registry.c (README, "Adding a
 * renderer").
 */
#ifndef REFLCHECK_REGISTRY_H
#define REFLCHECK_REGISTRY_H

#include <stddef.h>

#include "renderer.h"

typedef struct {
    const char *name;    /* in scene files, CLI options, job records, output file names */
    const char *title;   /* for people: "POV-Ray 3.7" */
    const char *program; /* the executable, NULL = renders in process */
    const char *package; /* the Debian package that installs program */
    const char *version; /* the version line of an in-process renderer (else: program --version) */
    int is_model;        /* computes reflcheck's own model: its exact coverage, object and N.V
                            layers mask every comparison, and it may go below 0 where the
                            model does */
    int stochastic;      /* samples and seeds reach the image (and the record) */
    unsigned partial[3]; /* per role: the terms (RENDERER_TERM_*) it may leave out when it
                            cannot reproduce them; the record names those it did */
    const char *cannot;  /* what it cannot reproduce at all (the job is skipped) */
    int cube_maps;       /* a program that looks a cube map (j->env) up itself; one without
                            gets the cube's equirectangular conversion (harness/jobs.c) */
    int crease_rules;    /* the CREASE_RULE_* bits (harness/crease.h) by which it shades with the
                            triangle's normal as well as the interpolated one, each shown by a
                            render of the program (tests/crease_renderers.sh); 0 = none: compare
                            moves the model's pixels where one departs out of the surface into
                            a region of their own */
    renderer_render_fn render;
    renderer_physics_fn physics; /* a physical reference: the physics its validate renders (renderer.h);
                                    NULL = it computes the model, not a physics */
} renderer_row;

int registry_count(void);
/* Row i, or NULL when i is out of range. */
const renderer_row *registry_row(int i);
/* The row's name, "?" when i is out of range. */
const char *registry_name(int i);
int registry_find(const char *name);
/* The renderer that computes the model itself (masks come from it); -1 if none. */
int registry_model(void);
/* The names as "a, b or c" for messages; returns buf. */
const char *registry_list(char *buf, size_t len);

#endif
