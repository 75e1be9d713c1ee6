# common.gp - look shared by every reflcheck report plot (loaded by angle.gp, trend.gp, time.gp).
# SVG at a fixed size; the page scales it with CSS. Titles and keys are noenhanced because
# comparison ids contain '_' which enhanced text would turn into subscripts.
set encoding utf8
set terminal svg size 560,340 font 'Helvetica,11' background rgb 'white'
set output outfile
set datafile missing '?'
set border 3 lc rgb '#57606a'
set tics nomirror textcolor rgb '#24292f'
set grid xtics ytics mytics lc rgb '#d0d7de' lw 0.6 dt 1, lc rgb '#eaeef2' lw 0.4
set key top left reverse Left noenhanced font ',9' samplen 2 spacing 1.1 box lc rgb '#d0d7de' opaque
set title ptitle noenhanced font ',11'
set style line 1 lc rgb '#0969da' lw 1.6 pt 7 ps 0.6
set style line 2 lc rgb '#cf222e' lw 1.6 pt 5 ps 0.6
set style line 3 lc rgb '#1a7f37' lw 1.6 pt 9 ps 0.7
set style line 4 lc rgb '#8250df' lw 1.6 pt 11 ps 0.7
set style line 5 lc rgb '#bf8700' lw 1.6 pt 13 ps 0.7
set style line 6 lc rgb '#1b7c83' lw 1.6 pt 4 ps 0.6
set style line 7 lc rgb '#6e7781' lw 1.6 pt 6 ps 0.6
set style line 8 lc rgb '#e16f24' lw 1.6 pt 8 ps 0.6
set style increment user
set logscale y
set format y '10^{%L}'
