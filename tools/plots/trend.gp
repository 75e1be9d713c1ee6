# trend.gp - surface relative RMS error of each comparison over the runs in reports/history.jsonl.
# tools/report.py calls:
#   gnuplot -e "datafile='x.dat'; ncols=5; ptitle='...'; outfile='y.svg'" trend.gp
# Data: header ("run label id1 id2 ..."), then run number, short commit, one value per comparison;
# '?' where a run lacks the comparison.
load dir.'common.gp'
set xlabel 'run (commit)'
set ylabel 'surface rel\_rms'
set xtics rotate by -35 font ',8'
set offsets 0.5, 0.5, 0, 0
set bmargin 5
plot for [i=3:ncols] datafile using 1:i:xtic(2) with linespoints ls (i-2) title columnhead(i)
