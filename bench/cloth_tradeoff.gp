# Speed against stretch of `felt bench cloth --tradeoff`: frame cost (x, median wall ms, log)
# against max structural stretch - 1 (y, log), one curve per method (Felt's four sweeps of its
# settings and its sweeps without the finishing worklist, Bullet's btSoftBody with and without bending links, iterations swept), one column per
# grid, the release stretch above and the settled stretch below. The shipped Felt setting is
# starred; the dashed line is the 10 % target; the key (short names of the report's curves) sits
# in the first panel. Only completed, judged points are drawn (the table lists the others). The
# bench runs this itself next to its CSV:
#   gnuplot -e "csv='bench/results/cloth_tradeoff.csv'; png='bench/results/cloth_tradeoff.png'; \
#               grids='32 64 128'" bench/cloth_tradeoff.gp
# CSV columns (see its header): 1 curve, 2 grid, 5 shipped, 10 frame_ms_median,
# 13 release_max_stretch, 14 settled_max_stretch, 16 status, 17 judged, last: host.
if (!exists("csv")) csv = 'bench/results/cloth_tradeoff.csv'
if (!exists("png")) png = 'bench/results/cloth_tradeoff.png'
if (!exists("grids")) grids = '32 64 128'
curves = 'felt_substeps felt_sweeps felt_small_steps felt_limit felt_sweeps_alone bullet_bending bullet_links'
titles = "'Felt substeps' 'Felt sweeps' 'Felt small steps' 'Felt tighter limit' 'Felt sweeps alone' 'Bullet + bending' 'Bullet links only'"
colors = '#1f77b4 #2ca02c #9467bd #17becf #7f7f7f #d62728 #ff7f0e'
points = '7 5 9 11 13 6 4'
ncols = words(grids)

# The rows of one curve on one grid that ran to the end and are judged (awk on the CSV).
sel(c, g) = sprintf("< awk -F, 'NR > 1 && $1 == \"%s\" && $2 == %s && $16 == \"ok\" && $17 == 1' %s", c, g, csv)
shipped(g) = sprintf("< awk -F, 'NR > 1 && $2 == %s && $5 == 1 && $16 == \"ok\"' %s", g, csv)
host = system("awk -F, 'NR == 2 { print $NF }' " . csv)

set datafile separator ','
set terminal pngcairo size (520 * ncols), 980 font ',10'
set output png
set logscale xy
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set format y '%g'
set yrange [0.005:*]
set xlabel 'ms per 60 Hz frame (median wall time, log)'
set multiplot layout 2, ncols \
    title sprintf("Cloth: frame cost against max structural stretch\nFelt and Bullet btSoftBody, host: %s", host) noenhanced
do for [row = 1:2] {
  col = (row == 1 ? 13 : 14)
  do for [k = 1:ncols] {
    g = word(grids, k)
    set title sprintf("%s x %s: %s", g, g, row == 1 ? "release transient (max over every frame)" : "settled (max over the timed frames)") noenhanced
    set ylabel 'max stretch - 1 (log)'
    # The key once, in the first panel's empty top right (curve ids: the report's table).
    if (row == 1 && k == 1) {
      set key top right samplen 2 font ',8' noenhanced box opaque
    } else {
      unset key
    }
    plot for [i = 1:words(curves)] sel(word(curves, i), g) using 10:(column(col) - 1) \
           with linespoints pt (word(points, i) + 0) ps 1.1 lw 1.5 lc rgb word(colors, i) \
           title word(titles, i), \
         shipped(g) using 10:(column(col) - 1) with points pt 3 ps 3 lw 2 lc rgb 'black' \
           title 'Felt shipped', \
         0.10 with lines dashtype 2 lc rgb 'black' title 'stretch 1.10'
  }
}
unset multiplot
