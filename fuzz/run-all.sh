#!/bin/sh
# Runs the three targets one after another (one worker each); logs in logs/.
# Usage: ./run-all.sh RECIPE_SECONDS SCENE_SECONDS RENDER_SECONDS
set -u
cd "$(dirname "$0")"
mkdir -p logs corpus/recipe corpus/scene corpus/render
run() {
    RUSTC_BOOTSTRAP=1 cargo fuzz run -s none "$1" "corpus/$1" "seeds/$1" -- \
        -max_total_time="$2" -timeout=10 -rss_limit_mb=2048 -max_len=16384 \
        -print_final_stats=1 > "logs/$1.log" 2>&1
    echo "$1 exit $?" >> logs/summary.txt
}
run recipe "${1:-600}"
run scene "${2:-300}"
run render "${3:-600}"
