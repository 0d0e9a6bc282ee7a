# Error against cost of the cloth integrators, log-log, one series per integrator and one panel per
# row set. Data: integrators_plot.dat written by `felt bench integrators` (one block per (set,
# integrator), eight integrators per set, header line "<integrator> ms rms_error_m", then rows
# "substeps ms error"). The bench runs this script itself when gnuplot is installed:
#   gnuplot -e "dat='bench/results/integrators_plot.dat'; png='bench/results/integrators.png'; \
#               panels=3; t1='32 x 32, Provot off'; t2='64 x 64, Provot off'; \
#               t3='32 x 32, Provot on (scene default)'" bench/plot_integrators.gp
if (!exists("dat")) dat = 'bench/results/integrators_plot.dat'
if (!exists("png")) png = 'bench/results/integrators.png'
if (!exists("panels")) panels = 3
if (!exists("t1")) t1 = '32 x 32, Provot off'
if (!exists("t2")) t2 = '64 x 64, Provot off'
if (!exists("t3")) t3 = '32 x 32, Provot on (scene default)'

set terminal pngcairo size (600 * panels), 560 font ',10'
set output png
set logscale xy
set format x '10^{%T}'
set format y '10^{%T}'
set xlabel 'ms per 60 Hz frame (median wall time)'
set ylabel 'RMS position error after 2 s [m]'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key bottom left font ',9' noenhanced
set datafile missing 'NaN'
set multiplot layout 1, panels
do for [p = 0:panels - 1] {
  set title (p == 0 ? t1 : p == 1 ? t2 : t3)
  plot for [i = 0:7] dat index (8 * p + i) using 2:3 with linespoints pt (i + 4) lw 1.5 \
       title columnheader(1)
}
unset multiplot
