# Plot of `felt bench haptic`: per snapshot mode, RMS force error against the truth (y, log) and
# median tick cost (x, thread CPU us), one point per trace (filled: bundled and --trace traces;
# open: recordings/hard/). The bench runs this itself next to its CSV:
#   gnuplot -e "csv='bench/results/haptic.csv'; png='bench/results/haptic.png'; \
#               modes='newest blend_forces interpolate extrapolate'; hard=1" bench/haptic.gp
# `modes` is the bench's kSnapshotModes list (proxy/proxy_spec.h), so a new mode needs no edit
# here. CSV columns (see its header): 1 group, 2 trace, 3 variant, 5 force_rms_error_N,
# 13 tick_us_median, 16 host. The truth's rows (error 0) are not plotted; errors below 1e-4 N
# are drawn at 1e-4 N (log axis).
if (!exists("csv")) csv = 'bench/results/haptic.csv'
if (!exists("png")) png = 'bench/results/haptic.png'
if (!exists("modes")) modes = 'newest blend_forces interpolate extrapolate'
if (!exists("hard")) hard = 0
floor = 1e-4
set datafile separator ','
set datafile missing 'NaN'
set terminal pngcairo size 900,620 font ',10'
set output png
# The host, from the CSV's first data row.
host = system("awk -F, 'NR == 2 { print $NF }' " . csv)
set title sprintf("Snapshot modes against the truth (1 kHz two-way cloth): error against tick cost\nhost: %s", host) noenhanced
set logscale y
set grid
set key outside right top font ',9' noenhanced
set xlabel 'tick cost, median thread CPU time per HapticTick [us]'
set ylabel 'RMS force error against the truth [N]'
set xrange [0:*]
set arrow from 10, graph 0 to 10, graph 1 nohead dashtype 2 lc 'black'
set label 'tick target 10 us' at 10, graph 0.97 offset 0.5, 0 font ',8'
rms(m) = (strcol(3) eq m) ? ($5 > floor ? $5 : floor) : NaN
target = 0.15
if (hard) {
  plot for [i = 1:words(modes)] csv skip 1 \
         using 13:(strcol(1) ne 'hard' ? rms(word(modes, i)) : NaN) \
         with points pt 7 ps 1.3 lc i title word(modes, i), \
       for [i = 1:words(modes)] csv skip 1 \
         using 13:(strcol(1) eq 'hard' ? rms(word(modes, i)) : NaN) \
         with points pt 6 ps 1.5 lc i title word(modes, i) . ' (hard)', \
       target with lines dashtype 2 lc 'red' title 'target 0.15 N'
} else {
  plot for [i = 1:words(modes)] csv skip 1 using 13:(rms(word(modes, i))) \
         with points pt 7 ps 1.3 lc i title word(modes, i), \
       target with lines dashtype 2 lc 'red' title 'target 0.15 N'
}
