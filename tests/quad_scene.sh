# quad_scene.sh - sourced by the nightly's shell tests: a Lambert quad under a sun whose only
# comparison is raster against its POV-Ray twin, cheap enough for a whole nightly in seconds.
#   quad_scene FILE NAME WIDTH [REL_RMS]   writes FILE; WIDTH pixels wide (16 high, k = 2);
#                                          REL_RMS, when given, the twin's rel_rms warn and fail
quad_scene() {
    {
        cat <<YAML
name: $2
image: {width: $3, height: 16, supersample: 2}
camera: {eye: [0, 2, 3], target: [0, 0, 0], hfov: 40}
lights:
  - {type: sun, direction: [0.2, -1, -0.3], irradiance: [3, 3, 3]}
materials:
  m: {albedo: [0.5, 0.4, 0.3], model: d3d}
objects:
  - {shape: quad, center: [0, 0, 0], size: [6, 6], material: m}
comparisons:
  - reference: povray
    role: twin
YAML
        [ -z "${4:-}" ] || printf '    thresholds:\n      rel_rms: {warn: %s, fail: %s, why: "test threshold"}\n' "$4" "$4"
    } > "$1"
}
