# angle.gp - surface relative RMS error per angle bin (N.V or N.L), one line per comparison.
# harness/report.py calls:
#   gnuplot -e "datafile='x.dat'; ncols=4; xlab='N·V'; ptitle='...'; outfile='y.svg'" angle.gp
# Data: header line ("bin", then comparison ids), then bin centre and one rel_rms per comparison;
# '?' marks a bin without pixels (or an exact 0, which a log axis cannot show).
load dir.'common.gp'
set xlabel xlab.' (bin centre)'
set ylabel 'surface rel\_rms'
set xrange [0:1]
set xtics 0.1
plot for [i=2:ncols] datafile using 1:i with linespoints ls (i-1) title columnhead(i)
