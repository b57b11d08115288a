#!/usr/bin/env bash
# Run the test suite: unit tests in one pytest process, each integration file in its own.
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh || exit 1
. .venv/bin/activate
export PYTHONDONTWRITEBYTECODE=1 MPLBACKEND=Agg
# numpy's OpenBLAS starts a thread per core for every call: beside the other test worker on
# two cores those threads wait on each other (the residual loop's small least-squares fits took
# 4-35 ms each against 0.2-0.8 ms on one thread; a helper's profile). One thread per process;
# a value given in the environment is kept.
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}
# DDS traffic of tests stays on this machine and apart from other runs
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$(( $$ % 100 + 100 ))}
passed=0; failed=0; status=0
summarise() {  # read pytest's closing line counts
  local out=$1
  local p f e
  p=$(grep -Eo '[0-9]+ passed' "$out" | tail -1 | cut -d' ' -f1); f=$(grep -Eo '[0-9]+ failed' "$out" | tail -1 | cut -d' ' -f1)
  e=$(grep -Eo '[0-9]+ error' "$out" | tail -1 | cut -d' ' -f1)
  passed=$((passed + ${p:-0})); failed=$((failed + ${f:-0} + ${e:-0}))
}
tmp=$(mktemp -d)
echo "== unit tests"
# the unit tests need no ROS and share nothing across files: one worker per core (pytest-xdist,
# a file's tests stay together so its module fixtures are built once). The tests that talk to a
# peer thread on a pseudo-terminal (servo-bus emulator, supply, load cell) run afterwards on
# their own, so that their reply deadlines do not compete with the other worker for the CPU.
# (test_dxl_review_fixes and _review_d assert that no reply came late: 3 failed beside a
# loaded other worker; test_dxl_emulator_sdk_clients' Bulk Read timed out once on a host at
# load 8, so every test with a servo-bus, supply or load-cell peer runs here, 18 s in all)
timed=(test/unit/test_dxl_bus.py test/unit/test_dxl_emulator.py test/unit/test_dxl_models.py
       test/unit/test_power_backends.py test/unit/test_force_backend.py
       test/unit/test_dxl_review_fixes.py test/unit/test_dxl_review_d.py
       test/unit/test_dxl_review_hw.py test/unit/test_dxl_xseries_current.py
       test/unit/test_dxl_emulator_sdk_clients.py test/unit/test_dxl_review_s.py
       test/unit/test_dxl_core_no_ros.py test/unit/test_integ_review_hw.py
       test/unit/test_power_force_review.py test/unit/test_review_quadruped_commands.py)
if [ "$(nproc 2>/dev/null || echo 1)" -ge 2 ]; then
  ignore=(); for f in "${timed[@]}"; do ignore+=(--ignore "$f"); done
  python -m pytest -q -p no:cacheprovider -n 2 --dist loadfile "${ignore[@]}" test/unit "$@" 2>&1 | tee "$tmp/unit.log"
  rc=${PIPESTATUS[0]}; [ "$rc" -eq 0 ] || [ "$rc" -eq 5 ] || status=1
  summarise "$tmp/unit.log"
  echo "== unit tests with pseudo-terminal peers"
  python -m pytest -q -p no:cacheprovider "${timed[@]}" "$@" 2>&1 | tee "$tmp/unit.log"
else
  python -m pytest -q -p no:cacheprovider test/unit "$@" 2>&1 | tee "$tmp/unit.log"
fi
rc=${PIPESTATUS[0]}; [ "$rc" -eq 0 ] || [ "$rc" -eq 5 ] || status=1
summarise "$tmp/unit.log"
# Integration tests: each file in its own process (rclpy's context and DDS participants do not
# outlive it), two files at a time, one per core: each file on a ROS domain of its own, so the
# two running side by side never discover each other's nodes. Longest first (test_demo), so the
# lanes end together; each file's log is printed whole when it ends.
run_integration() {  # [PYTEST ARGS...] FILE INDEX (xargs appends the last two)
  local f=${*: -2:1} i=${*: -1}
  set -- "${@:1:$(( $# - 2 ))}"
  local log="$tmp/int_$i.log"
  ROS_DOMAIN_ID=$(( (domain0 + i) % 100 + 100 )) \
    python -m pytest -q -p no:cacheprovider "$f" "$@" > "$log" 2>&1
  echo "$?" > "$log.rc"
  { flock 9; echo "== $f"; cat "$log"; } 9> "$tmp/print.lock"
}
export -f run_integration
export tmp domain0=$ROS_DOMAIN_ID
lanes=$(( $(nproc 2>/dev/null || echo 1) >= 2 ? 2 : 1 ))
# test_energy_live_sim asserts a live simulated robot's power: late gait commands on a loaded
# host make its servos step (97 W read for 35 W beside the other lane and two busy processes),
# so it runs after the lanes, on its own
alone=(test/integration/test_energy_live_sim.py)
files=(test/integration/test_demo.py)
for f in test/integration/test_*.py; do
  [ "$f" = "${files[0]}" ] || [ "$f" = "${alone[0]}" ] || files+=("$f")
done
for i in "${!files[@]}"; do printf '%s\0%s\0' "${files[$i]}" "$i"; done |
  xargs -0 -n 2 -P "$lanes" bash -c 'run_integration "$@"' _ "$@"
for f in "${alone[@]}"; do files+=("$f"); run_integration "$@" "$f" $(( ${#files[@]} - 1 )); done
for i in "${!files[@]}"; do
  rc=$(cat "$tmp/int_$i.log.rc" 2>/dev/null || echo 1)
  [ "$rc" -eq 0 ] || [ "$rc" -eq 5 ] || { status=1; echo "FAILED: ${files[$i]} (exit $rc)"; }
  summarise "$tmp/int_$i.log"
done
rm -rf "$tmp"
echo "$passed passed, $failed failed"
[ "$passed" -gt 0 ] || status=1
exit $status
