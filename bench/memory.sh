#!/usr/bin/env bash
# Peak memory and wall time of the file verbs against the recording's length (BENCHMARKS.md,
# "The file verbs read as they go"). Usage: bench/memory.sh NEW_PHYSID [OLD_PHYSID] [DIR]
# Writes shaft-D.{parquet,mf4}, motored-D.parquet and fired-D.parquet into DIR (≈ 30 GB with
# the one-hour files) and prints a Markdown row per measurement (inspect/monitor, the fits, filter,
# the crank-angle verbs, identify and run). ONLY=crank measures the crank-angle verbs alone,
# ONLY=passes identify and run alone (the last part; DURATIONS="75 600" to choose), ONLY=torque
# torque fit in passes alone (DURATIONS likewise), ONLY=compression compression fit in passes,
# ONLY=mdf MDF4 in several groups and written compressed (bench/mdf_groups.py needs asammdf),
# ONLY=counts the verbs on a time-basis file whose angle is an encoder's counts, ONLY=wheel on
# one whose angle is a trigger wheel's raw signal (bench/wheel_file.py needs pyarrow, numpy).
set -euo pipefail
NEW=$(realpath "$1"); OLD=${2:+$(realpath "$2")}; DIR=${3:-/tmp/physid-memory}
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
mkdir -p "$DIR" && cd "$DIR"
m() { /usr/bin/time -f "%M %e" -o t.out "$@" > /dev/null 2> err.out || { echo "failed: $(tail -1 err.out)"; return; }
      read -r kb s < t.out; echo "$(( kb / 1024 )) MB, ${s} s"; }
if [ -z "${ONLY:-}" ]; then
for D in 75 150 300 600 3600; do
  for ext in parquet mf4; do
    [ -f "shaft-$D.$ext" ] || "$NEW" simulate --scenario shaft-steady --duration "$D" --recording "shaft-$D.$ext" > /dev/null
  done
done
for D in 75 150 300 600; do
  [ -f "motored-$D.parquet" ] || "$NEW" simulate --scenario friction-sweep --duration "$D" --recording "motored-$D.parquet" > /dev/null
  [ -f "fired-$D.parquet" ] || "$NEW" simulate --scenario torque-steady --duration "$D" --recording "fired-$D.parquet" > /dev/null
done
for D in 75 150 300 600 3600; do
  for ext in parquet mf4; do
    cat "shaft-$D.$ext" > /dev/null  # into the page cache for both builds
    row="| $D s | $ext | $(m "$NEW" inspect "shaft-$D.$ext" --json) |"
    [ -n "$OLD" ] && [ "$D" != 3600 ] && row="$row $(m "$OLD" inspect "shaft-$D.$ext" --json) |"
    row="$row $(m "$NEW" monitor shaft --data "shaft-$D.$ext" --json) |"
    [ -n "$OLD" ] && [ "$D" != 3600 ] && row="$row $(m "$OLD" monitor shaft --data "shaft-$D.$ext" --json) |"
    echo "$row"
  done
done
for D in 75 150 300 600; do
  row="| $D s | $(m "$NEW" friction fit --data "motored-$D.parquet" --json) |"
  [ -n "$OLD" ] && row="$row $(m "$OLD" friction fit --data "motored-$D.parquet" --json) |"
  row="$row $(m "$NEW" torque fit --data "fired-$D.parquet" --json) |"
  [ -n "$OLD" ] && row="$row $(m "$OLD" torque fit --data "fired-$D.parquet" --json) |"
  echo "$row"
done
for D in 75 150 300 600; do
  cat "shaft-$D.parquet" > /dev/null
  row="| $D s | $(m "$NEW" filter "shaft-$D.parquet" f.parquet --lowpass 500 --channels torque_shaft,theta_en) |"
  [ -n "$OLD" ] && row="$row $(m "$OLD" filter "shaft-$D.parquet" f.parquet --lowpass 500 --channels torque_shaft,theta_en) |"
  echo "$row"
done
for D in 75 150 300 600; do
  [ -f "deg-$D.parquet" ] || "$NEW" simulate --scenario friction-sweep --basis crank --duration "$D" --recording "deg-$D.parquet" > /dev/null
  cat "deg-$D.parquet" > /dev/null
  row="| $D s | $(m "$NEW" friction fit --data "deg-$D.parquet" --json) |"
  [ -n "$OLD" ] && row="$row $(m "$OLD" friction fit --data "deg-$D.parquet" --json) |"
  echo "$row"
done
fi
if [ -z "${ONLY:-}" ] || [ "${ONLY:-}" = crank ]; then
# The crank-angle verbs (ONLY=crank runs this part alone): on a time-basis file with theta_en
# (cycles, compression fit, convert --crank-angle), on a crank-angle file (cycles, monitor
# shaft, torque fit, convert --time-basis).
for D in 75 150 300 600; do
  [ -f "motored-$D.parquet" ] || "$NEW" simulate --scenario friction-sweep --duration "$D" --recording "motored-$D.parquet" > /dev/null
  [ -f "deg-$D.parquet" ] || "$NEW" simulate --scenario friction-sweep --basis crank --duration "$D" --recording "deg-$D.parquet" > /dev/null
  [ -f "shaftdeg-$D.parquet" ] || "$NEW" simulate --scenario shaft-steady --basis crank --duration "$D" --recording "shaftdeg-$D.parquet" > /dev/null
  [ -f "fireddeg-$D.parquet" ] || "$NEW" simulate --scenario torque-steady --basis crank --duration "$D" --recording "fireddeg-$D.parquet" > /dev/null
  cat "motored-$D.parquet" "deg-$D.parquet" "shaftdeg-$D.parquet" "fireddeg-$D.parquet" > /dev/null
  for cmd in "cycles motored-$D.parquet --json" \
             "compression fit --data motored-$D.parquet --stroke 0.0514 --rod 0.088 --json" \
             "convert motored-$D.parquet c.parquet --crank-angle" \
             "cycles deg-$D.parquet --json" \
             "monitor shaft --data shaftdeg-$D.parquet --json" \
             "torque fit --data fireddeg-$D.parquet --json" \
             "convert deg-$D.parquet c.parquet --time-basis 10000"; do
    # shellcheck disable=SC2086
    row="| $D s | \`$cmd\` | $(m "$NEW" $cmd) |"
    # The old build holds a compressed file's recording whole: ≈ 20 GB at one hour.
    # shellcheck disable=SC2086
    [ -n "$OLD" ] && { [ "$D" != 3600 ] || [ "${cmd#*--compression}" = "$cmd" ]; } && row="$row $(m "$OLD" $cmd) |"
    echo "$row"
  done
done
fi
# identify and run go over their file in passes (ONLY=passes runs this part alone): the shaft
# model on shaft-D.parquet, its five columns held within PHYSID_HOLD_MB (default 256) or read
# again on every pass (PHYSID_HOLD_MB=0).
if [ -z "${ONLY:-}" ] || [ "${ONLY:-}" = passes ]; then
SHAFT='K*(theta_dy - theta_en) + B*(omega_dy - omega_en) + tau0'
for D in ${DURATIONS:-75 150 300 600 3600}; do
  [ -f "shaft-$D.parquet" ] || "$NEW" simulate --scenario shaft-steady --duration "$D" --recording "shaft-$D.parquet" > /dev/null
  cat "shaft-$D.parquet" > /dev/null
  printf '[model]\nexpr = "%s"\nparams = { K = 1250.0, B = 0.95, tau0 = 0.1 }\noutput = "torque_shaft"\n[data]\nfile = "%s"\n[estimator]\nmethod = "dsfc"\nlambda = 0.999\n[objective]\nafter_s = 1.0\n' \
    "$SHAFT" "$DIR/shaft-$D.parquet" > "run-$D.toml"
  for what in identify run; do
    if [ $what = identify ]; then set -- identify --data "shaft-$D.parquet" --expr "$SHAFT" --params K=1250,B=0.95,tau0=0.1 --y torque_shaft --cutoff wu --json
    else set -- run "run-$D.toml" --json; fi
    row="| $D s | $what | $(m "$NEW" "$@") | $(PHYSID_HOLD_MB=0 m "$NEW" "$@") |"
    [ -n "$OLD" ] && [ "$D" != 3600 ] && row="$row $(m "$OLD" "$@") |"
    echo "$row"
  done
done
fi
# torque fit goes over its 1° samples in passes (ONLY=torque runs this part alone): a
# crank-angle file's rows read again, a time-basis file's read and resampled again, unless the
# channels fit PHYSID_HOLD_MB (default 256; 0: always read again).
if [ -z "${ONLY:-}" ] || [ "${ONLY:-}" = torque ]; then
for D in ${DURATIONS:-75 600 3600}; do
  [ -f "fireddeg-$D.parquet" ] || "$NEW" simulate --scenario torque-steady --basis crank --duration "$D" --recording "fireddeg-$D.parquet" > /dev/null
  files="fireddeg-$D.parquet"
  if [ "$D" != 3600 ]; then
    [ -f "fired-$D.parquet" ] || "$NEW" simulate --scenario torque-steady --duration "$D" --recording "fired-$D.parquet" > /dev/null
    files="$files fired-$D.parquet"
  fi
  for f in $files; do
    cat "$f" > /dev/null
    row="| $D s | $f | $(m "$NEW" torque fit --data "$f" --json) | $(PHYSID_HOLD_MB=0 m "$NEW" torque fit --data "$f" --json) |"
    [ -n "$OLD" ] && row="$row $(m "$OLD" torque fit --data "$f" --json) |"
    echo "$row"
  done
done
fi
# compression fit goes over its TDCs' windows in passes (ONLY=compression): held within
# PHYSID_HOLD_MB or gathered again from the file (PHYSID_HOLD_MB=0), on motored-D (a time basis
# with theta_en, resampled as it is read).
if [ -z "${ONLY:-}" ] || [ "${ONLY:-}" = compression ]; then
for D in ${DURATIONS:-75 600 3600}; do
  [ -f "motored-$D.parquet" ] || "$NEW" simulate --scenario friction-sweep --duration "$D" --recording "motored-$D.parquet" > /dev/null
  cat "motored-$D.parquet" > /dev/null
  set -- compression fit --data "motored-$D.parquet" --stroke 0.0514 --rod 0.088 --json
  row="| $D s | $(m "$NEW" "$@") | $(PHYSID_HOLD_MB=0 m "$NEW" "$@") |"
  [ -n "$OLD" ] && row="$row $(m "$OLD" "$@") |"
  echo "$row"
done
fi
# MDF4 as it comes (ONLY=mdf): groups-D.mf4 (bench/mdf_groups.py, asammdf: two groups on one
# 10 kHz time base and a slow one) read by inspect and convert; motored-D written compressed.
if [ -z "${ONLY:-}" ] || [ "${ONLY:-}" = mdf ]; then
for D in ${DURATIONS:-75 600 3600}; do
  [ -f "groups-$D.mf4" ] || python3 "$HERE/mdf_groups.py" "$D" "groups-$D.mf4"
  cat "groups-$D.mf4" > /dev/null
  for cmd in "inspect groups-$D.mf4 --json" "convert groups-$D.mf4 g.parquet" \
             "convert motored-$D.parquet z.mf4 --compression deflate" \
             "convert motored-$D.parquet z.mf4 --compression transposed"; do
    # shellcheck disable=SC2086
    row="| $D s | \`$cmd\` | $(m "$NEW" $cmd) |"
    # The old build holds a compressed file's recording whole: ≈ 20 GB at one hour.
    # shellcheck disable=SC2086
    [ -n "$OLD" ] && { [ "$D" != 3600 ] || [ "${cmd#*--compression}" = "$cmd" ]; } && row="$row $(m "$OLD" $cmd) |"
    echo "$row"
  done
done
fi
# A time-basis file whose angle is an encoder's counts (ONLY=counts): counts-D.parquet, 13 of
# the motored run's 35 channels (not theta_en), read three times over by the crank-angle verbs
# (the counts and the marker; then the channels with the counts read ahead); fcounts-D.parquet
# the fired run's channels without theta_en, for torque fit (no one-hour fired run: 75 and 600 s).
if [ -z "${ONLY:-}" ] || [ "${ONLY:-}" = counts ]; then
CH=t,count_en,count_dy,tdc,omega_en,alpha_en,p_cyl,p_int,p_crank,p_atm,T_oil,torque_engine,torque_shaft
for D in ${DURATIONS:-75 600 3600}; do
  [ -f "motored-$D.parquet" ] || "$NEW" simulate --scenario friction-sweep --duration "$D" --recording "motored-$D.parquet" > /dev/null
  [ -f "counts-$D.parquet" ] || "$NEW" convert "motored-$D.parquet" "counts-$D.parquet" --channels "$CH" > /dev/null
  cat "counts-$D.parquet" > /dev/null
  for cmd in "cycles counts-$D.parquet" "convert counts-$D.parquet cdeg.parquet --crank-angle" \
             "compression fit --data counts-$D.parquet --stroke 0.0514 --rod 0.088" \
             "friction fit --data counts-$D.parquet --json"; do
    # shellcheck disable=SC2086
    row="| $D s | \`$cmd\` | $(m "$NEW" $cmd) |"
    # shellcheck disable=SC2086
    [ -n "$OLD" ] && [ "$D" != 3600 ] && row="$row $(m "$OLD" $cmd) |"
    echo "$row"
  done
  # Not held: every pass of the fit reads the file three times (one hour: ≈ 30 min).
  [ "$D" != 3600 ] && echo "| $D s | \`compression fit\`, PHYSID_HOLD_MB=0 | $(PHYSID_HOLD_MB=0 m "$NEW" compression fit --data "counts-$D.parquet" --stroke 0.0514 --rod 0.088) |"
  if [ "$D" != 3600 ]; then
    [ -f "fired-$D.parquet" ] || "$NEW" simulate --scenario torque-steady --duration "$D" --recording "fired-$D.parquet" > /dev/null
    [ -f "fcounts-$D.parquet" ] || "$NEW" convert "fired-$D.parquet" "fcounts-$D.parquet" --channels "$CH" > /dev/null
    row="| $D s | \`torque fit --data fcounts-$D.parquet --json\` | $(m "$NEW" torque fit --data "fcounts-$D.parquet" --json) |"
    [ -n "$OLD" ] && row="$row $(m "$OLD" torque fit --data "fcounts-$D.parquet" --json) |"
    echo "$row"
  fi
done
fi
# A time-basis file whose angle is a raw sensor's signal (ONLY=wheel): wheel-D.parquet, 10 of
# the motored run's channels and a Hall sensor over a 60-2 wheel, quad-D.parquet the same with a
# 36-line quadrature encoder (bench/wheel_file.py; SENSORS="wheel quad" chooses), read over in
# passes by the crank-angle verbs (what must be known before any angle; the sensor and the
# pressure; then the channels with the sensor read ahead); then --tdc-from on the wheel
# (TDC_FROM=0 leaves it out).
if [ -z "${ONLY:-}" ] || [ "${ONLY:-}" = wheel ]; then
for D in ${DURATIONS:-75 600 3600}; do
  [ -f "motored-$D.parquet" ] || "$NEW" simulate --scenario friction-sweep --duration "$D" --recording "motored-$D.parquet" > /dev/null
  for S in ${SENSORS:-wheel quad}; do
    case $S in
      wheel) W="--wheel enc=60-2 --phase-from p_cyl"; X= ;;
      *) W="--quadrature qa,qb,qz=36 --phase-from p_cyl"; X=--quadrature ;;
    esac
    # shellcheck disable=SC2086
    [ -f "$S-$D.parquet" ] || python3 "$HERE/wheel_file.py" "motored-$D.parquet" "$S-$D.parquet" $X
    cat "$S-$D.parquet" > /dev/null
    for cmd in "cycles $S-$D.parquet $W" "convert $S-$D.parquet wdeg.parquet --crank-angle $W" \
               "compression fit --data $S-$D.parquet --stroke 0.0514 --rod 0.088 $W"; do
      # shellcheck disable=SC2086
      row="| $D s | \`${cmd% --*=*}\` | $(m "$NEW" $cmd) |"
      # shellcheck disable=SC2086
      [ -n "$OLD" ] && row="$row $(m "$OLD" $cmd) |"
      echo "$row"
    done
    # shellcheck disable=SC2086
    [ "$S" = wheel ] && echo "| $D s | \`inspect $S-$D.parquet --wheel enc=60-2 --json\` | $(m "$NEW" inspect "$S-$D.parquet" --wheel enc=60-2 --json) | ${OLD:+$(m "$OLD" inspect "$S-$D.parquet" --wheel enc=60-2 --json) |}"
    # Not held: every pass of the fit reads the file twice (it keeps what the first passes found).
    # shellcheck disable=SC2086
    [ "$D" != 3600 ] && echo "| $D s | \`compression fit --data $S-$D.parquet\`, PHYSID_HOLD_MB=0 | $(PHYSID_HOLD_MB=0 m "$NEW" compression fit --data "$S-$D.parquet" --stroke 0.0514 --rod 0.088 $W) |"
  done
  if [ "${TDC_FROM:-1}" = 1 ]; then
    cmd="convert wheel-$D.parquet wdeg.parquet --crank-angle --wheel enc=60-2 --phase-from p_cyl --tdc-from p_cyl --stroke 0.0514 --rod 0.088"
    # shellcheck disable=SC2086
    row="| $D s | \`convert wheel-$D.parquet --crank-angle --tdc-from p_cyl\` | $(m "$NEW" $cmd) |"
    # shellcheck disable=SC2086
    [ -n "$OLD" ] && row="$row $(m "$OLD" $cmd) |"
    echo "$row"
  fi
  rm -f wdeg.parquet
done
fi
