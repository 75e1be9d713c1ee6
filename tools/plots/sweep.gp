# sweep.gp - one scene's error-vs-time sweep (tools/sweep.py) on log-log axes: one series per
# renderer knob, the Pareto frontier over every point behind them, the raster as-is error as a
# dashed line and Cycles' crossover time as a dotted one.
# tools/report.py calls:
#   gnuplot -e "datafile='x.dat'; nseries=4; titles='\"cycles spp (...)\" \"raster k (...)\"'; \
#               ptitle='...'; xlab='...'; ylab='...'; hline=0.34; xcross=3.3; outfile='y.svg'" sweep.gp
# Data: block 0 the Pareto frontier, blocks 1..nseries the series in the order of titles
# (double-quoted words), each of "seconds error" lines, blocks separated by two blank lines.
# hline / xcross <= 0: not drawn.
load dir.'common.gp'
set terminal svg size 820,400 font 'Helvetica,11' background rgb 'white'
set output outfile
set logscale x
set format x '10^{%L}'
set xlabel xlab
set ylabel ylab noenhanced
set key outside right top vertical reverse Left noenhanced font ',9' samplen 2 spacing 1.1 nobox
set rmargin at screen 0.66
if (hline > 0) {
    set arrow 1 from graph 0, first hline to graph 1, first hline nohead dt 2 lw 1.2 lc rgb '#cf222e'
}
if (xcross > 0) {
    set arrow 2 from first xcross, graph 0 to first xcross, graph 1 nohead dt 3 lw 1.2 lc rgb '#0969da'
}
plot datafile index 0 using 1:2 with steps lw 7 lc rgb '#fff0b3' title 'Pareto frontier', \
     datafile index 0 using 1:2 with points pt 6 ps 1.6 lc rgb '#bf8700' notitle, \
     for [i=1:nseries] datafile index i using 1:2 with linespoints ls i title word(titles, i), \
     (hline > 0 ? 1/0 : 1/0) with lines dt 2 lw 1.2 lc rgb '#cf222e' title (hline > 0 ? 'raster as-is error' : ''), \
     (xcross > 0 ? 1/0 : 1/0) with lines dt 3 lw 1.2 lc rgb '#0969da' title (xcross > 0 ? 'Cycles crossover' : '')
