# Plot of `felt bench self-collision`: the cost of every frame over the animation, per run (like
# the per-frame timing figures of 002_a56e6b146de342b8.txt), one panel per row kind and grid:
# each method's frame wall time (solid) and its detection time (dashed; none for `off`, the same
# scene without self-collision), log scale. The bench runs this itself next to its CSV:
#   gnuplot -e "csv='bench/results/self_collision_frames.csv'; png='bench/results/self_collision.png'" \
#       bench/self_collision.gp
# CSV columns (header row): 1 kind, 2 method, 3 grid, 4 frame, 5 frame_ms, 6 detect_ms, 7 case,
# 8 host.
if (!exists("csv")) csv = 'bench/results/self_collision_frames.csv'
if (!exists("png")) png = 'bench/results/self_collision.png'
set datafile separator ','
set datafile missing 'NaN'
# The panels (kind:grid), the methods, the case and the host, from the CSV.
panels = system("awk -F, 'NR > 1 && !seen[$1 \":\" $3]++ { printf \"%s:%s \", $1, $3 }' " . csv)
methods = system("awk -F, 'NR > 1 && !seen[$2]++ { printf \"%s \", $2 }' " . csv)
case = system("awk -F, 'NR == 2 { print $7 }' " . csv)
host = system("awk -F, 'NR == 2 { print $8 }' " . csv)
n = words(panels)
set terminal pngcairo size 900, 330 * n + 60 font ',10'
set output png
set multiplot layout n, 1 title sprintf("felt bench self-collision, case %s: cost of each frame\nhost: %s", case, host) noenhanced
set logscale y
set grid
set key outside right top font ',9' noenhanced
set xlabel 'frame (1/60 s)'
set ylabel 'ms per frame'
kind_of(p) = p[1:strstrt(p, ':') - 1]
grid_of(p) = p[strstrt(p, ':') + 1:]
do for [i = 1:n] {
  p = word(panels, i)
  set title sprintf("%s rows, %s x %s", kind_of(p), grid_of(p), grid_of(p)) noenhanced
  plot for [j = 1:words(methods)] csv skip 1 \
         using 4:((strcol(1) eq kind_of(p) && strcol(3) eq grid_of(p) && strcol(2) eq word(methods, j)) ? $5 : NaN) \
         with lines lw 1.5 lc j title word(methods, j) . ' frame', \
       for [j = 1:words(methods)] csv skip 1 \
         using 4:((strcol(1) eq kind_of(p) && strcol(3) eq grid_of(p) && strcol(2) eq word(methods, j)) ? $6 : NaN) \
         with lines lw 1 dt 2 lc j title (word(methods, j) eq 'off' ? '' : word(methods, j) . ' detection')
}
unset multiplot
