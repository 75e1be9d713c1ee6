# angle.gp - error per angle bin (N.V, N.H or N.L), one line per column: surface rel_rms per
# comparison (logy=1), or a validate's share of the squared error per term and material (logy=0).
# tools/report/plots.py calls:
#   gnuplot -e "datafile='x.dat'; ncols=4; xlab='N·V'; ylab='...'; logy=1; height=340; ptitle='...'; outfile='y.svg'" angle.gp
# Data: header line ("bin", then column titles), then bin centre and one value per column;
# '?' marks a bin without pixels (or an exact 0 on a log axis, which cannot show it).
load dir.'common.gp'
# The key goes below the plot area, outside it, so no line or point is ever behind it; the
# caller makes the SVG taller by one key row per two columns.
set terminal svg size 560,height font 'Helvetica,11' background rgb 'white'
set output outfile
set key outside below left Left reverse horizontal maxcols 2 noopaque nobox
set xlabel xlab.' (bin centre)'
set ylabel ylab noenhanced
set xrange [0:1]
set xtics 0.1
if (!logy) {
    unset logscale y
    set format y '%g'
    set yrange [0:*]
}
plot for [i=2:ncols] datafile using 1:i with linespoints ls ((i-2) % 8 + 1) title columnhead(i)
