# Plot of `felt bench collision`: repair ms and swept-query us against the triangle count.
# Usage: gnuplot -e "csv='bench/results/collision.csv'; png='bench/results/collision.png'" \
#          bench/collision.gp
# (`felt bench collision --plot` runs exactly this.) Columns: see the CSV header; 3 = triangles,
# 4 = repair_ms_median, 10 = query_us_median, 15 = query_us_max_rerun.
if (!exists("csv")) csv = 'bench/results/collision.csv'
if (!exists("png")) png = 'bench/results/collision.png'
set datafile separator ','
set datafile missing 'NaN'
set terminal pngcairo size 1400,560 font ',10'
set output png
set multiplot layout 1,2 title "Collision structures on a swinging cloth (001 Tables 2-3 layout)"
set logscale xy
set grid
set key top left font ',8'
set xlabel 'triangles'

set title 'repair per frame (median, ms)'
set ylabel 'ms'
repair = "bvh-sphere-2-bottomup bvh-aabb-2-bottomup bvh-sphere-4-bottomup bvh-aabb-4-bottomup bvh-aabb-4-queue bvh-aabb-4-bottomup-d5mm bvh-sphere-4-topdown bvh-aabb-4-rebuild osh"
plot for [s in repair] csv skip 1 using 3:(strcol(1) eq s ? $4 : NaN) with linespoints title s, \
     0.05 with lines dashtype 2 lc 'black' title 'target at 4802 triangles: 0.05 ms'

set title 'swept-sphere query per haptic tick (median, us)'
set ylabel 'us'
query = "naive osh bvh-sphere-2-bottomup bvh-aabb-2-bottomup bvh-sphere-4-bottomup bvh-aabb-4-bottomup bvh-aabb-4-bottomup-d5mm"
plot for [s in query] csv skip 1 using 3:(strcol(1) eq s ? $10 : NaN) with linespoints title s, \
     2 with lines dashtype 2 lc 'black' title 'target at 32258 triangles: 2 us'
unset multiplot
