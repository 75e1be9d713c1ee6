# figure1_scene.gp - Figure 1 for a scene's own materials: each material's reflectance against
# the angle of incidence under its model (solid) beside its physics' Fresnel (dashed, same colour),
# from `reflcheck eval materials SCENE` (cli/cli_eval.c) through tools/report/plots.py:
#   gnuplot -e "datafile='x.dat'; nmat=2; height=380; ptitle='...'; outfile='y.svg'; dir='tools/plots/'" figure1_scene.gp
# Data: header line ("angle", then <material>:model and <material>:physics per material), then
# the angle in degrees and the two values of each material.
load dir.'common.gp'
# The key sits below the plot area, so no curve is ever behind it; the caller adds one key row
# of height per material.
set terminal svg size 560,height font 'Helvetica,11' background rgb 'white'
set output outfile
set key outside below left Left reverse horizontal maxcols 2 noopaque nobox
unset logscale y
set format y '%g'
set xrange [0:90]
set xtics 10
set yrange [0:*]
set xlabel 'angle of incidence θ [deg], cos θ = N·V'
set ylabel 'reflectance (mean of R, G, B)' noenhanced
plot for [i=1:nmat] datafile using 1:(column(2*i)) with lines ls ((i-1) % 8 + 1) lw 2 title columnhead(2*i), \
     for [i=1:nmat] datafile using 1:(column(2*i+1)) with lines ls ((i-1) % 8 + 1) dt 2 title columnhead(2*i+1)
