#!/bin/bash
# Submits a sharded `smartagg study` to Slurm: a job array of N shards
# (study-array.sbatch), then a merge job (study-merge.sbatch) that starts
# when every shard has succeeded (--dependency=afterok:<array job id>).
# Prints both job ids. See tools/slurm/README.md.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
usage() {
    cat <<USAGE
usage: submit.sh --experiment STUDY --shards N --results DIR [--binary PATH]
                 [--sbatch-arg ARG]... [--dry-run] [-- STUDY_ARGS...]
  --experiment STUDY  smart-vs-fixed, future-spad, cameras, objective,
                      hot-pixels or localizers (the studies that shard)
  --shards N          array tasks, one shard each (1..1000)
  --results DIR       shared folder: DIR/shard-I-of-N, DIR/merged, DIR/logs
  --binary PATH       the smartagg binary on the compute nodes
                      (default: smartagg on PATH)
  --sbatch-arg ARG    passed to both sbatch calls (e.g. --partition=short)
  --dry-run           print the sbatch commands instead of running them
  STUDY_ARGS          passed to every shard (e.g. --blinks-per-point 2000)
USAGE
}
die() {
    echo "submit.sh: $*" >&2
    exit 2
}

study=
shards=
results=
binary=
dry_run=0
sbatch_args=()
while [ "$#" -gt 0 ]; do
    case $1 in
    --experiment) study=${2:-}; shift 2 || die "--experiment needs a value" ;;
    --shards) shards=${2:-}; shift 2 || die "--shards needs a value" ;;
    --results) results=${2:-}; shift 2 || die "--results needs a value" ;;
    --binary) binary=${2:-}; shift 2 || die "--binary needs a value" ;;
    --sbatch-arg) sbatch_args+=("${2:-}"); shift 2 || die "--sbatch-arg needs a value" ;;
    --dry-run) dry_run=1; shift ;;
    -h | --help) usage; exit 0 ;;
    --) shift; break ;;
    *) usage >&2; die "unknown option '$1'" ;;
    esac
done
study_args=("$@")

case $study in
smart-vs-fixed | future-spad | cameras | objective | hot-pixels | localizers) ;;
"") usage >&2; die "--experiment is required" ;;
*) die "'$study' does not run in shards (smart-vs-fixed, future-spad, cameras, objective, hot-pixels, localizers)" ;;
esac
if ! [[ $shards =~ ^[1-9][0-9]*$ ]] || [ "$shards" -gt 1000 ]; then
    die "--shards must be an integer in 1..1000, not '$shards'"
fi
[ -n "$results" ] || die "--results is required"
if [ -z "$binary" ]; then
    binary=$(command -v smartagg) || die "no smartagg on PATH: give --binary"
fi
[ -x "$binary" ] || die "--binary $binary is not executable"
for a in "${study_args[@]}"; do
    case $a in
    --shard | --shard=* | --out | --out=*) die "$a is set by submit.sh, not a study argument" ;;
    esac
done
# Absolute paths: the jobs run in other directories, on other nodes.
case $results in /*) ;; *) results=$PWD/$results ;; esac
case $binary in /*) ;; *) binary=$(cd "$(dirname "$binary")" && pwd)/$(basename "$binary") ;; esac

array_cmd=(sbatch --parsable --export=ALL "${sbatch_args[@]}" --array="1-$shards"
    --output="$results/logs/study-%A_%a.out"
    "$here/study-array.sbatch" "$study" "$shards" "$results" "$binary" "${study_args[@]}")
merge_cmd=(sbatch --parsable --export=ALL "${sbatch_args[@]}"
    --output="$results/logs/merge-%j.out")

if [ "$dry_run" = 1 ]; then
    printf '%q ' "${array_cmd[@]}"
    echo
    printf '%q ' "${merge_cmd[@]}" --dependency=afterok:ARRAY_JOB_ID \
        "$here/study-merge.sbatch" "$shards" "$results" "$binary"
    echo
    exit 0
fi

command -v sbatch >/dev/null || die "sbatch not found: run this on a Slurm login node"
mkdir -p "$results/logs"
array_id=$("${array_cmd[@]}")
array_id=${array_id%%;*}
[[ $array_id =~ ^[0-9]+$ ]] || die "sbatch returned '$array_id', not a job id"
merge_id=$("${merge_cmd[@]}" --dependency="afterok:$array_id" \
    "$here/study-merge.sbatch" "$shards" "$results" "$binary")
merge_id=${merge_id%%;*}
echo "array job $array_id ($shards shards of $study), merge job $merge_id (after all succeed)"
echo "results: $results/merged (shards in $results/shard-I-of-$shards, logs in $results/logs)"
