# A pool of CI jobs, sourced by .ci/run: `pool_add NAME 'COMMAND'` queues a
# job, `pool_run DURATIONS [KNOWN]` runs them at most $CI_JOBS at a time (default: the
# number of cores) and fails if any failed.
#
# Why: the tests run on software rasterisers, and one test binary keeps only
# about 1.3 of two cores busy (a test waits on a readback, a
# subprocess, an X server, a browser). Binaries in separate processes share no
# adapter, temporary folder, port or X display, so they run side by side.
#
# Jobs start longest first, by the durations the last run on this machine wrote
# to DURATIONS (unknown jobs first), so that a long job does not start last. A
# machine that has none yet (a fresh one: the run that matters most) orders
# them by KNOWN, the durations committed beside this file (.ci/durations.txt).
# Each job's output is captured and printed whole when it ends, under a line
# with its name, result and time.

pool_names=()
pool_cmds=()

pool_add() {
  pool_names+=("$1")
  pool_cmds+=("$2")
}

pool_run() {
  local durations=$1 jobs=${CI_JOBS:-$(nproc)} logs i name secs order_from=$1
  [ -s "$durations" ] || order_from=${2:-$1}
  logs=$(mktemp -d)
  # Known durations, longest first; a job never seen before counts as longest.
  local order=()
  while read -r _ i; do order+=("$i"); done < <(
    for i in "${!pool_names[@]}"; do
      name=${pool_names[$i]}
      secs=$(awk -F '\t' -v n="$name" '$2 == n { print $1 }' "$order_from" 2>/dev/null | tail -n 1 || true)
      echo "${secs:-999999} $i"
    done | sort -k1,1nr -k2,2n
  )
  echo "running ${#order[@]} jobs, $jobs at a time"
  local started=$SECONDS
  for i in "${order[@]}"; do
    while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
    (
      begin=$SECONDS
      if (eval "${pool_cmds[$i]}") >"$logs/$i.log" 2>&1 </dev/null; then result=ok; else result=FAILED; touch "$logs/$i.failed"; fi
      took=$((SECONDS - begin))
      printf '%s\t%s\n' "$took" "${pool_names[$i]}" >>"$logs/durations"
      {
        flock 9
        echo "::: ${pool_names[$i]}: $result in ${took} s"
        cat "$logs/$i.log"
      } 9>"$logs/print.lock"
    ) &
  done
  wait
  echo "all jobs ended in $((SECONDS - started)) s; longest:"
  touch "$logs/durations"
  sort -k1,1nr "$logs/durations" | head -n 8 | awk -F '\t' '{ printf "  %5d s  %s\n", $1, $2 }'
  # Kept for the next run's order (a failed job's time too: it is still the time it takes).
  if [ -n "$durations" ]; then cp "$logs/durations" "$durations" 2>/dev/null || true; fi
  local failed=()
  for i in "${!pool_names[@]}"; do [ -f "$logs/$i.failed" ] && failed+=("${pool_names[$i]}"); done
  rm -rf "$logs"
  if [ ${#failed[@]} -gt 0 ]; then
    echo "failed jobs: ${failed[*]}"
    return 1
  fi
}
