# time.gp - error against render time on log-log axes, one series per renderer or setting.
# tools/report.py calls:
#   gnuplot -e "datafile='x.dat'; nseries=2; titles='cycles povray'; ptitle='...'; outfile='y.svg'" time.gp
# Data: blocks of "seconds error" lines separated by two blank lines, in the order of titles.
load dir.'common.gp'
set logscale x
set format x '10^{%L}'
set xlabel 'render time (s)'
set ylabel 'error'
set key top right
plot for [i=0:nseries-1] datafile index i using 1:2 with linespoints ls (i+1) title word(titles, i+1)
