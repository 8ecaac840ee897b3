#!/usr/bin/env bash
# One task of a lapidary batch job per element of a Slurm array:
#   N=$(lapidary batch job.ron | wc -l)
#   jid=$(sbatch --parsable --array=0-$((N - 1)) examples/farm/slurm-array.sh job.ron)
#   sbatch --dependency=afterok:$jid examples/farm/slurm-merge.sh job.ron
# A task whose tile is already complete skips it, so re-queueing the array
# (or `scontrol requeue`) resumes. LAPIDARY names the binary if it is not
# on PATH.
#SBATCH --job-name=lapidary
#SBATCH --output=lapidary-%A_%a.log
#SBATCH --cpus-per-task=1
set -euo pipefail
exec "${LAPIDARY:-lapidary}" batch "$1" --task "$SLURM_ARRAY_TASK_ID" \
    --threads "${SLURM_CPUS_PER_TASK:-1}" -q
