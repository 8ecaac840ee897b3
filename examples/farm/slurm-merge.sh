#!/usr/bin/env bash
# The merge step of a lapidary batch job, after its array (see
# slurm-array.sh): every image from its tiles, and the turntables'
# animated PNGs.
#SBATCH --job-name=lapidary-merge
#SBATCH --output=lapidary-%j-merge.log
set -euo pipefail
exec "${LAPIDARY:-lapidary}" batch "$1" --merge
