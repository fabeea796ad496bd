# Sourced by .ci/run and .ci/test.sh: `step NAME COMMAND...` runs a step, names it, and
# times it; the steps' times are printed as a table when the script ends (pass or fail), so
# every CI log records where its minutes went (results/README.md keeps the figures).
STEPS_TIMES=()
step() {
    local name=$1 start=$SECONDS rc=0
    shift
    echo "== $name"
    "$@" || rc=$?
    STEPS_TIMES+=("$(printf '%6d s  %s%s' $((SECONDS - start)) "$name" "$([ $rc = 0 ] || echo " (failed, exit $rc)")")")
    return $rc
}
steps_summary() {
    [ ${#STEPS_TIMES[@]} -gt 0 ] || return 0
    echo "== steps of $(basename "$0"), wall-clock seconds"
    printf '%s\n' "${STEPS_TIMES[@]}"
}
trap steps_summary EXIT
