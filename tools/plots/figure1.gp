# figure1.gp - Figure 1 of the D3D9Client note ("Reflection intensity as function of angle"):
# R = R0 + (1 - R0)(1 - cos theta)^p for p = 2 (red) and p = 4 (blue), R0 = 0.04 (n = 1.5),
# with the exact unpolarised Fresnel reflectance of n = 1.5 overlaid, and below it the error of
# each Schlick-style variant (p = 2, 4 and Schlick's own p = 5) against the exact curve.
#
# Input: three CSV files written by `reflcheck eval fresnel` (cli/cli_eval.c), columns
#   angle_deg, cos_theta, d3d9_R, schlick5, exact_dielectric, d3d9_minus_exact, schlick5_minus_exact
# Run (from the repository root, after `make`):
#   mkdir -p build/fig1
#   for p in 2 4 5; do build/reflcheck eval fresnel --ior 1.5 --p $p --steps 900 > build/fig1/p$p.csv; done
#   gnuplot -e "dir='build/fig1'" tools/plots/figure1.gp                      -> build/fig1/figure1.svg
#   gnuplot -e "dir='build/fig1'; fmt='png'" tools/plots/figure1.gp           -> build/fig1/figure1.png
# gnuplot-nox has the svg and pngcairo terminals (`gnuplot -e 'set terminal'`); svg is the default.

if (!exists("dir")) dir = "build/fig1"
if (!exists("fmt")) fmt = "svg"
if (fmt eq "png") {
    set terminal pngcairo size 900,900 font "sans,11"
} else {
    set terminal svg size 900,900 font "sans,11" background "white"
}
set output sprintf("%s/figure1.%s", dir, fmt)

p2 = dir."/p2.csv"
p4 = dir."/p4.csv"
p5 = dir."/p5.csv"
set datafile separator ","

set multiplot layout 2,1 title "D3D9Client Fresnel (1)/(3): R = R_0 + (1 - R_0)(1 - cos {/Symbol q})^p, R_0 = 0.04 (n = 1.5)"
set xrange [0:90]
set xtics 0,10,90
set grid
set key left top

set title "Reflection intensity as function of angle (note's Figure 1, with the exact curve)"
set ylabel "R"
set yrange [0:1]
plot p2 using 1:3 skip 1 with lines lw 2 lc rgb "#d62728" title "p = 2", \
     p4 using 1:3 skip 1 with lines lw 2 lc rgb "#1f77b4" title "p = 4", \
     p5 using 1:5 skip 1 with lines lw 2 dt 2 lc rgb "black" title "exact Fresnel, n = 1.5"

set title "Error against the exact Fresnel reflectance"
set xlabel "angle of incidence {/Symbol q} [deg]"
set ylabel "R_{approx} - R_{exact}"
set autoscale y
set key left top
plot p2 using 1:6 skip 1 with lines lw 2 lc rgb "#d62728" title "p = 2", \
     p4 using 1:6 skip 1 with lines lw 2 lc rgb "#1f77b4" title "p = 4", \
     p5 using 1:7 skip 1 with lines lw 2 lc rgb "#2ca02c" title "p = 5 (Schlick)", \
     0 with lines lc rgb "gray" notitle
unset multiplot
