#!/usr/bin/env bash
# Behaviour preserved: every verb's JSON (provenance aside), every file written, every error
# message and exit status of physid at BASE and at HEAD (default: the working tree), byte for
# byte, on the shipped pipelines, the demo, each built-in scenario in each format and basis, the
# raw-sensor files (a 60-2 wheel, a quadrature encoder) and the fuzz corpus (issue 42).
#
# Usage: scripts/same-output.sh BASE [HEAD]      e.g. scripts/same-output.sh 5190322
#
# Each revision is built in a worktree of its own (a release build without LTO: the same
# floating-point operations as the shipped build, minutes instead of ten), into one shared target
# directory ($SAME_OUTPUT_DIR, default /tmp/same-output). The commands are in `commands` below;
# each runs in a fresh directory per revision, and its stdout, stderr, exit status and every file
# it leaves are compared. Normalised before comparing: the `provenance` object of a JSON result
# (date, command line, input checksums), the provenance block and build date of an HTML report,
# and the elapsed-time fields `wall_s`/`elapsed_s`. Needs git, cargo, python3 with numpy and
# pyarrow (for the raw-sensor files). Exits 1 on any difference, listing the files.
set -euo pipefail

base=${1:?usage: scripts/same-output.sh BASE [HEAD]}
head=${2:-}
root=$(git rev-parse --show-toplevel)
dir=${SAME_OUTPUT_DIR:-/tmp/same-output}
mkdir -p "$dir"
export CARGO_TARGET_DIR=$dir/target CARGO_PROFILE_RELEASE_LTO=off \
    CARGO_PROFILE_RELEASE_CODEGEN_UNITS=16 CARGO_PROFILE_RELEASE_DEBUG=0

# build REV NAME: the physid binary of REV (a worktree) or of the working tree (REV empty) at
# $dir/NAME.
build() {
    local rev=$1 name=$2 src=$root
    # SAME_OUTPUT_REUSE=1: the binaries already there (a rerun after changing only this script).
    [[ -n ${SAME_OUTPUT_REUSE:-} && -x $dir/$name/physid ]] && return 0
    if [[ -n $rev ]]; then
        src=$dir/src-$name
        git -C "$root" worktree remove --force "$src" 2>/dev/null || rm -rf "$src"
        git -C "$root" worktree add --detach "$src" "$rev" >/dev/null
    fi
    (cd "$src" && cargo build --release -q -p physid --bin physid)
    mkdir -p "$dir/$name"
    cp "$CARGO_TARGET_DIR/release/physid" "$dir/$name/physid"
    [[ -n $rev ]] && git -C "$root" worktree remove --force "$src"
    return 0
}

# The commands, one per line, run with `physid` the binary under test, in one directory (later
# commands read what earlier ones wrote). `%ROOT%` is the repository.
commands() {
    cat <<'EOF'
physid simulate --list
physid simulate --list-params
physid simulate --scenario shaft-steady --duration 4 --recording steady.parquet
physid simulate --scenario shaft-steady --duration 2 --fault shaft.k=1000@1 --recording steady.csv
physid simulate --scenario shaft-ramp --duration 2 --recording ramp.mf4
physid simulate --scenario torque-ramp --duration 3 --recording torque.parquet
physid simulate --scenario torque-steady --duration 2 --basis crank --recording crank.parquet
physid simulate --scenario friction-sweep --duration 8 --sample-rate 2000 --recording friction.parquet
physid simulate --scenario fig314 --duration 3 --sample-rate 1000 --recording fig314.csv
physid simulate motored-cycle --json
physid simulate compression --json
physid simulate dyno-curve --json
physid inspect steady.parquet --json
physid inspect ramp.mf4 --json
physid inspect crank.parquet --json
physid monitor shaft --data steady.parquet --json
physid monitor shaft --data steady.csv --json --tracks shaft-tracks.csv
physid monitor shaft --data ramp.mf4 --method dsfc --json
physid monitor shaft --data crank.parquet --json
physid friction eval --n 1500 --p-int 60 --t-oil 90 --json
physid friction rank --json
physid friction fit --data friction.parquet --json --tracks friction-tracks.parquet
physid torque fit --data torque.parquet --json --tracks torque-tracks.csv
physid torque fit --data torque.parquet --method ekf --json
physid compression fit --data torque.parquet --stroke 0.09 --rod 0.15 --json
physid compression fit --data crank.parquet --stroke 0.09 --rod 0.15 --compression-ratio 10 --json
physid cycles torque.parquet --json --tracks cycles.csv
physid cycles crank.parquet --json
physid identify --data steady.parquet --expr "K*(theta_dy - theta_en) + B*(omega_dy - omega_en)" --params K=1250,B=0.95 --y torque_shaft --json
physid identify --data torque.parquet --model cyclic-torque --map theta=theta_en --map omega=omega_en --map alpha=alpha_en --json
physid estimate --data steady.parquet --y torque_shaft --phi "theta_dy - theta_en,omega_dy - omega_en" --method rlsf --json --tracks est-rlsf.csv
physid estimate --data steady.parquet --y torque_shaft --phi "theta_dy - theta_en,omega_dy - omega_en" --method rlsvf --lambdas 0.99,0.995 --json
physid estimate --data steady.parquet --y torque_shaft --phi "theta_dy - theta_en,omega_dy - omega_en" --method kf --r1 1e-6 --r2 0.01 --json
physid estimate --data steady.parquet --y torque_shaft --phi "theta_dy - theta_en,omega_dy - omega_en" --method dsfc --lambda 0.999 --json
physid estimate --data steady.parquet --y torque_shaft --phi "theta_dy - theta_en,omega_dy - omega_en" --method rls --json
physid estimate --data steady.parquet --y torque_shaft --phi "theta_dy - theta_en,omega_dy - omega_en" --method rlsf --lambda0 0.95 --json
physid estimate --data steady.parquet --y torque_shaft --expr "K*(theta_dy - theta_en) + B*(omega_dy - omega_en)" --params K=1200,B=1 --method ukf --r2 0.01 --json --tracks est-ukf.parquet
physid estimate --data steady.parquet --y torque_shaft --expr "K*(theta_dy - theta_en) + B*(omega_dy - omega_en)" --params K=1200,B=1 --method srukf --r2 0.01 --json
physid estimate --data steady.parquet --y torque_shaft --expr "K*(theta_dy - theta_en) + B*(omega_dy - omega_en)" --params K=1200,B=1 --method ekf --r2 0.01 --scaled --limits K=100:5000 --json
physid run %ROOT%/pipelines/shaft-expr.toml --json --out run-shaft
physid run %ROOT%/pipelines/torque-ramp.toml --json --out run-torque
physid convert steady.parquet steady-out.mf4
physid convert steady.csv steady-out.parquet
physid convert torque.parquet torque-crank.csv --crank-angle --step-deg 2
physid filter steady.parquet steady-lp.parquet --lowpass 200 --channels torque_shaft
physid example --help
physid live --replay steady.parquet --headless --json --pace max
physid live --replay torque.parquet --headless --json --pace max --torque
physid live --replay friction.parquet --headless --json --pace max --friction cell
physid demo --out demo
python3 %ROOT%/bench/wheel_file.py steady.parquet wheel.parquet
python3 %ROOT%/bench/wheel_file.py steady.parquet quad.parquet --quadrature
physid inspect wheel.parquet --wheel enc=60-2 --json
physid convert quad.parquet quad-crank.csv --crank-angle --quadrature qa,qb,qz=36
physid convert wheel.parquet wheel-crank.parquet --crank-angle --wheel enc=60-2
physid cycles wheel.parquet --wheel enc=60-2 --json
physid cycles wheel.parquet --wheel enc=60-2 --tdc-from p_cyl --stroke 0.09 --rod 0.15 --json
physid cycles quad.parquet --quadrature qa,qb,qz=36 --json
EOF
    for f in "$root"/crates/io/tests/fuzz/crashes/*.parquet; do
        echo "physid inspect $f --json"
        echo "physid monitor shaft --data $f --json"
    done
}

# run BIN OUT: every command with BIN as physid, in OUT.
run() {
    local bin=$1 out=$2 i=0 line
    rm -rf "$out" && mkdir -p "$out/files"
    while IFS= read -r line; do
        i=$((i + 1))
        line=${line//%ROOT%/$root}
        local id
        id=$(printf %03d $i)
        echo "$line" >"$out/$id.cmd"
        (cd "$out/files" && PHYSID="$bin" bash -c "physid() { \"\$PHYSID\" --quiet \"\$@\"; }; $line" \
            >"../$id.stdout" 2>"../$id.stderr"; echo $? >"../$id.rc") || true
    done < <(commands)
}

# Normalise the run-dependent parts in place (see the header).
normalise() {
    python3 - "$1" <<'EOF'
import json, pathlib, re, sys
DROP = {"provenance", "wall_s", "elapsed_s", "seconds", "updates_per_s"}
# Elapsed times in the verbs' text.
TIMES = [(r"in [0-9.]+ s, [0-9.]+× real time", "in T s, R× real time"),
         (r"(the virtual test cell), [0-9.]+ s", r"\1, T s")]
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if k not in DROP}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
for p in pathlib.Path(sys.argv[1]).rglob("*"):
    if not p.is_file():
        continue
    if p.suffix in (".stdout", ".json"):
        text = p.read_text(errors="replace")
        try:
            p.write_text(json.dumps(strip(json.loads(text)), sort_keys=False, indent=1))
        except ValueError:
            lines = text.splitlines()
            try:
                # NDJSON (live --headless --json): each line.
                p.write_text("".join(json.dumps(strip(json.loads(l))) + "\n" for l in lines))
                continue
            except ValueError:
                pass
            for pattern, by in TIMES:
                text = re.sub(pattern, by, text)
            p.write_text(text)
    elif p.suffix == ".mf4":
        # The start time of the header block (HD) and of the file history (FH): a u64 after
        # the block's 24-byte header and its links (HD: 6, FH: 2).
        data = bytearray(p.read_bytes())
        for block, links in ((b"##HD", 6), (b"##FH", 2)):
            at = data.find(block)
            if at >= 0:
                t = at + 24 + 8 * links
                data[t:t + 8] = bytes(8)
        p.write_bytes(bytes(data))
    elif p.suffix == ".html":
        text = p.read_text(errors="replace")
        text = re.sub(r"<section[^>]*provenance.*?</section>", "", text, flags=re.S)
        text = re.sub(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?Z?", "DATE", text)
        p.write_text(text)
EOF
}

# The raw-sensor files are written by python3 with numpy and pyarrow: without them every
# command on those files fails alike at both revisions and would compare as "same".
if ! python3 -c "import numpy, pyarrow" 2>/dev/null; then
    echo "same-output: needs python3 with numpy and pyarrow (pip install numpy pyarrow)" >&2
    exit 2
fi
build "$base" base
build "$head" head
run "$dir/base/physid" "$dir/out-base"
run "$dir/head/physid" "$dir/out-head"
# A command that makes files for the others (python3) must have worked.
for out in "$dir/out-base" "$dir/out-head"; do
    for cmd in "$out"/*.cmd; do
        if [[ $(cat "$cmd") == python3* && $(cat "${cmd%.cmd}.rc") != 0 ]]; then
            echo "same-output: $(cat "$cmd") failed: $(cat "${cmd%.cmd}.stderr")" >&2
            exit 2
        fi
    done
done
normalise "$dir/out-base"
normalise "$dir/out-head"
if diff -rq "$dir/out-base" "$dir/out-head"; then
    echo "same output: $(ls "$dir/out-base"/*.cmd | wc -l) commands, $(find "$dir/out-base/files" -type f | wc -l) files, byte for byte (BASE $base, HEAD ${head:-working tree})"
else
    echo "DIFFERENT (above); the outputs are in $dir/out-base and $dir/out-head" >&2
    exit 1
fi
