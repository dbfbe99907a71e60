#!/usr/bin/env bash
# Run one closed-loop experiment over DDS: recorder, controller, trajectory and plant nodes.
#
# usage: run_experiment.sh --robot R --contour C --controller K --out bags/NAME
#                          [--scenario S] [--mode lockstep|realtime] [--rate HZ]
#                          [--duration-factor F] [--smc-reading NAME] [--timeout SECONDS]
#                          [--param NAME:=VALUE ...] [--params-file FILE] [--composed | --compose NODES] [--keep-going]
#                          [--respawn controller] [--nice N] [--intra-process] [--from-description]
#                          [--viewer [--viewer-port PORT]]
#        run_experiment.sh --stand-in ROBOT --controller K --out bags/NAME [--seconds S] [--rate HZ (1000)]
#                          [--realism ideal|bench] [--driver-param NAME:=VALUE ...]
#                          [--param NAME:=VALUE ...] [--params-file FILE] [--timeout SECONDS]
#
# Starts the four nodes (each with `ros2 run pdsmc_ros ...`; with --composed, all four in one
# process; with --compose plant,controller, those in one process and the others apart), waits
# for the end of the trajectory, and exits non-zero naming any node that failed (a plant whose arm
# diverged -- a non-finite or runaway state -- fails, and the script says so). On timeout or Ctrl-C it
# stops the nodes it started, by PID, recorder last. Node logs go to OUT.logs/.
# When a node dies the others get 3 s (the plant's watchdog acts and the recorder records it)
# before they are stopped; with --keep-going they run on. --respawn controller restarts the
# controller 1 s after it dies, up to 3 times, like launch's respawn: the plant's safe mode
# supervises the arm meanwhile and the run resumes when the new controller answers.
# --nice N starts the plant and the controller (the loop's critical path) at niceness N, e.g.
# -10 (negative values need root; without it they run at normal priority, with a warning).
# --viewer also starts the live viewer (its own process, an observer the loop never waits for):
# open ws://localhost:8765 (or --viewer-port) in Foxglove with "Open connection".
# --from-description: only the plant is given --robot; the other nodes take the arm from the
# plant's /robot_description (robot:=/robot_description; separate processes only).
# --intra-process (with --composed or --compose) hands messages between the composed nodes
# without DDS, like rclcpp's intra-process comms; nodes in other processes still get them.
# --stand-in ROBOT: a real arm's graph instead of the pipeline: the MuJoCo stand-in for the arm
# (mujoco_driver; --realism PRESET: its nuisances, ideal by default or bench), the controller in real
# time (--controller; --param, --params-file: its gains, joints...) and the recorder in graph mode
# beside them (/joint_states, the stand-in's true state, the commands,
# /controller/controller_state, the /controller/follow_joint_trajectory action's status, feedback
# and results, /diagnostics, /robot_description: docs/recording.md). It runs for --seconds (default:
# until Ctrl-C or --timeout) while any FollowJointTrajectory client sends goals, then stops the
# nodes, recorder last; `pdsmc analyze OUT` gives the figures of each goal. --driver-param gives the
# stand-in one of its parameters (a nuisance replacing the preset's: payload_mass:=2.0, seed:=3).
set -uo pipefail

usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; }
die() { echo "run_experiment.sh: error: $*" >&2; exit 2; }

ROBOT="" CONTOUR="" CONTROLLER="" OUT="" SCENARIO="nominal" MODE="lockstep" RATE=""
FACTOR="" SMC_READING="" TIMEOUT="600" COMPOSE="" KEEP_GOING=0 NICE="" INTRA=0 FROM_DESCRIPTION=0
VIEWER=0 VIEWER_PORT=8765 STAND_IN="" RUN_SECONDS="" REALISM="" DRIVER_EXTRA=()
EXTRA=()
FILES=()  # ROS 2 params files: each node reads its own section (e.g. `pdsmc tune`'s controller gains)
declare -A RESPAWN=()
RESPAWN_MAX=3
RESPAWN_DELAY=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --robot) ROBOT="${2:-}"; shift 2 ;;
    --contour) CONTOUR="${2:-}"; shift 2 ;;
    --controller) CONTROLLER="${2:-}"; shift 2 ;;
    --out) OUT="${2:-}"; shift 2 ;;
    --scenario) SCENARIO="${2:-}"; shift 2 ;;
    --mode) MODE="${2:-}"; shift 2 ;;
    --rate) RATE="${2:-}"; shift 2 ;;
    --duration-factor) FACTOR="${2:-}"; shift 2 ;;
    --smc-reading) SMC_READING="${2:-}"; shift 2 ;;
    --timeout) TIMEOUT="${2:-}"; shift 2 ;;
    --param) EXTRA+=(-p "${2:-}"); shift 2 ;;
    --driver-param) DRIVER_EXTRA+=(-p "${2:-}"); shift 2 ;;
    --params-file)
      [[ -f "${2:-}" ]] || die "--params-file: no such file '${2:-}'"
      FILES+=(--params-file "$2"); shift 2 ;;
    --composed) COMPOSE="recorder,controller,trajectory,plant"; shift ;;
    --compose) COMPOSE="${2:-}"; shift 2 ;;
    --keep-going) KEEP_GOING=1; shift ;;
    --nice) NICE="${2:-}"; shift 2 ;;
    --intra-process) INTRA=1; shift ;;
    --from-description) FROM_DESCRIPTION=1; shift ;;
    --viewer) VIEWER=1; shift ;;
    --stand-in) STAND_IN="${2:-}"; [[ -n "$STAND_IN" ]] || die "--stand-in needs a robot (e.g. serial_3r, ur5)"; shift 2 ;;
    --realism) REALISM="${2:-}"; [[ "$REALISM" == ideal || "$REALISM" == bench ]] || die "--realism must be ideal or bench, got '$REALISM'"; shift 2 ;;
    --seconds)
      [[ "${2:-}" =~ ^[0-9]+$ && "${2:-}" -gt 0 ]] || die "--seconds must be a whole number of seconds > 0, got '${2:-}'"
      RUN_SECONDS="$2"; shift 2 ;;
    --viewer-port)
      [[ "${2:-}" =~ ^[0-9]+$ && "${2:-}" -le 65535 ]] || die "--viewer-port must be a port number 0-65535, got '${2:-}'"
      VIEWER_PORT="$2"; shift 2 ;;
    --respawn)
      case "${2:-}" in
        controller) RESPAWN[$2]=0 ;;
        *) die "--respawn takes controller (the node that can rejoin a running loop), got '${2:-}'" ;;
      esac
      shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done
if [[ -z "$STAND_IN" ]]; then
  [[ -n "$ROBOT" ]] || die "--robot is required (serial_3r or parallel_5r)"
  [[ -n "$CONTOUR" ]] || die "--contour is required"
  [[ -z "$RUN_SECONDS" ]] || die "--seconds goes with --stand-in (a pipeline run ends with its trajectory)"
  [[ -z "$REALISM" ]] || die "--realism goes with --stand-in (the pipeline's plant is the arm's own model)"
  [[ ${#DRIVER_EXTRA[@]} -eq 0 ]] || die "--driver-param goes with --stand-in (the stand-in's parameters)"
else
  [[ -z "$ROBOT" && -z "$CONTOUR" && -z "$COMPOSE" && "$FROM_DESCRIPTION" == 0 && "$VIEWER" == 0 ]] \
    || die "--stand-in runs the driver, the controller and the recorder apart; it takes no --robot, --contour, --composed, --compose, --from-description or --viewer"
fi
[[ -n "$CONTROLLER" ]] || die "--controller is required (pd, smc or pdsmc)"
[[ -n "$OUT" ]] || die "--out is required (a new bag directory, e.g. bags/run1)"
[[ "$MODE" == lockstep || "$MODE" == realtime ]] || die "--mode must be lockstep or realtime, got '$MODE'"
[[ "$TIMEOUT" =~ ^[0-9]+$ && "$TIMEOUT" -gt 0 ]] || die "--timeout must be a whole number of seconds > 0, got '$TIMEOUT'"
if [[ -n "$NICE" ]]; then
  [[ "$NICE" =~ ^-?[0-9]+$ && "$NICE" -ge -20 && "$NICE" -le 19 ]] || die "--nice must be a whole number in [-20, 19], got '$NICE'"
fi
[[ -e "$OUT" ]] && die "--out '$OUT' already exists; choose a new bag directory"
[[ "$FROM_DESCRIPTION" == 1 && -n "$COMPOSE" ]] && die "--from-description needs the nodes in their own processes (a composed node would wait for a plant composed after it)"
# the nodes run in one process (composed), each in the canonical start order
NODE_NAMES=(recorder controller trajectory plant)
declare -A IN_GROUP=()
if [[ -n "$COMPOSE" ]]; then
  IFS=',' read -r -a _group <<< "$COMPOSE"
  for name in "${_group[@]}"; do
    case "$name" in
      recorder|controller|trajectory|plant) IN_GROUP[$name]=1 ;;
      *) die "--compose takes a comma-separated list of recorder, controller, trajectory, plant; got '$COMPOSE'" ;;
    esac
  done
  [[ ${#IN_GROUP[@]} -ge 2 ]] || die "--compose needs at least two different nodes, got '$COMPOSE'"
  COMPOSE_LIST="$(for n in "${NODE_NAMES[@]}"; do [[ -n "${IN_GROUP[$n]:-}" ]] && printf '%s,' "$n"; done)"
  COMPOSE_LIST="${COMPOSE_LIST%,}"
fi
[[ "$INTRA" == 0 || -n "$COMPOSE" ]] || die "--intra-process needs --composed or --compose NODES (it joins nodes of one process)"
for name in "${!RESPAWN[@]}"; do
  [[ -z "${IN_GROUP[$name]:-}" ]] || die "--respawn $name needs $name in a process of its own (not composed)"
done
# the process that runs the plant: its end ends a real-time run
PLANT_PROC=plant
[[ -n "${IN_GROUP[plant]:-}" ]] && PLANT_PROC=composed

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
if command -v ros2 >/dev/null 2>&1; then
  ROS2=(ros2)
elif [[ -x "$HERE/../.venv/bin/ros2" ]]; then
  ROS2=("$HERE/../.venv/bin/ros2")
  export AMENT_PREFIX_PATH="${AMENT_PREFIX_PATH:-$(cd "$HERE/../.venv" && pwd)}"
else
  die "no ros2 command found: activate the venv (source .venv/bin/activate) or run make setup"
fi

# Keep concurrent runs apart: a DDS domain of our own unless the caller chose one.
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( ($$ % 100) + 100 ))}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
# Fast DDS: drop dead participants after 2 s (config/fastdds_profile.xml)
if [[ -z "${FASTRTPS_DEFAULT_PROFILES_FILE:-}" && -f "$HERE/../config/fastdds_profile.xml" ]]; then
  export FASTRTPS_DEFAULT_PROFILES_FILE="$(cd "$HERE/../config" && pwd)/fastdds_profile.xml"
fi

PARAMS=(-p "robot:=$ROBOT" -p "contour:=$CONTOUR" -p "type:=$CONTROLLER" -p "scenario:=$SCENARIO" -p "mode:=$MODE")
[[ -n "$RATE" ]] && PARAMS+=(-p "rate:=$RATE")
[[ -n "$FACTOR" ]] && PARAMS+=(-p "duration_factor:=$FACTOR")
[[ -n "$SMC_READING" ]] && PARAMS+=(-p "smc_reading:=$SMC_READING")
if [[ "$MODE" == lockstep ]]; then PARAMS+=(-p "use_sim_time:=true"); fi
PARAMS=("${FILES[@]}" "${PARAMS[@]}" "${EXTRA[@]}")

LOGS="$OUT.logs"
mkdir -p "$LOGS" || die "cannot create log directory '$LOGS'"

declare -A PIDS=()
ORDER=()
start_node() {
  local name="$1"; shift
  local pre=() launcher=()
  [[ "$name" == composed ]] && pre=(--nodes "$COMPOSE_LIST")
  [[ "$name" == composed && "$INTRA" == 1 ]] && pre+=(--intra-process)
  # the loop's critical path (plant, controller, or the process composing them) may run niced
  if [[ -n "$NICE" && ( "$name" == plant || "$name" == controller || \
        ( "$name" == composed && ( -n "${IN_GROUP[plant]:-}" || -n "${IN_GROUP[controller]:-}" ) ) ) ]]; then
    launcher=(nice -n "$NICE")
  fi
  local own=()
  [[ "$FROM_DESCRIPTION" == 1 && "$name" != plant ]] && own=(-p "robot:=/robot_description")
  "${launcher[@]}" "${ROS2[@]}" run pdsmc_ros "$name" "${pre[@]}" --ros-args "${PARAMS[@]}" "${own[@]}" "$@" \
    >>"$LOGS/$name.log" 2>&1 &
  PIDS[$name]=$!
}

declare -A KILLED=()
# the order stop_all stops nodes in: the plant first, the recorder last so it loses nothing; a
# stand-in run stops the controller before the arm's driver, as on a real arm (the driver takes
# the controller's last zero command, and the controller is not left to find its plant gone)
STOP_ORDER=(plant trajectory controller composed viewer mujoco_driver recorder)
stop_all() {
  # stop what we started, by PID, in STOP_ORDER
  local name pid
  for name in "${STOP_ORDER[@]}"; do
    pid="${PIDS[$name]:-}"
    [[ -n "$pid" ]] && kill -0 "$pid" 2>/dev/null || continue
    kill -INT "$pid" 2>/dev/null
    for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    if kill -0 "$pid" 2>/dev/null; then
      kill -KILL "$pid" 2>/dev/null
      KILLED[$name]=1
    fi
  done
}

# A node that finished its work and then hung in Fast DDS's teardown is ended by its own
# teardown watch with SIGALRM (status 142, pdsmc_ros.loop.lifecycle.EXIT_TEARDOWN_HUNG): its
# outputs are complete, so that is a warning, not a failure. Prints the status to judge by.
TEARDOWN_HUNG=142
outcome() {
  local name="$1" code="$2"
  if [[ "$code" -eq $TEARDOWN_HUNG ]]; then
    echo "run_experiment.sh: warning: node '$name' finished its work, then hung in DDS teardown and was ended by its teardown watch (stack in $LOGS/$name.log)" >&2
    code=0
  fi
  echo "$code"
}

# one line on why a node failed: its exit code and the last line of its log
explain() {
  local name="$1" code="$2" how="exit $2"
  [[ -n "${KILLED[$name]:-}" ]] && how="still running 5 s after SIGINT; killed"
  echo "run_experiment.sh: node '$name' failed ($how): $(tail -n 1 "$LOGS/$name.log" 2>/dev/null)" >&2
}
trap 'echo "run_experiment.sh: interrupted, stopping nodes" >&2; stop_all; exit 130' INT TERM

# Real time: the plant's time starts with the first command, and the controller commands (holds)
# as soon as its loop runs; a trajectory node whose loop starts later (locking memory can take
# seconds) would miss the motion. So the process with the plant starts once every other loop
# process says its loop runs ("real time: ..." in its log), or waits for the arm the plant
# publishes (--from-description: it cannot run before the plant), or has ended, or after 120 s.
wait_for_loops() {
  local deadline=$((SECONDS + 120)) proc
  for proc in "${ORDER[@]}"; do
    [[ "$proc" == recorder || "$proc" == viewer ]] && continue
    while kill -0 "${PIDS[$proc]}" 2>/dev/null \
        && ! grep -q -e ']: real time: ' -e ']: waiting for the arm on ' "$LOGS/$proc.log" 2>/dev/null \
        && [[ $SECONDS -lt $deadline ]]; do
      sleep 0.1
    done
  done
}

# --stand-in: the driver, the controller and the recorder in graph mode, for --seconds or until stopped
if [[ -n "$STAND_IN" ]]; then
  # one rate for the driver and the controller: the driver's 1 kHz unless --rate (the controller's
  # own default, the thesis preset's 10 kHz, would find every state of a 1 kHz driver stale)
  RATE_PARAM=(-p "rate:=${RATE:-1000.0}")
  STOP_ORDER=(controller mujoco_driver recorder)
  start_own() {
    local name="$1"; shift
    "${ROS2[@]}" run pdsmc_ros "$name" --ros-args "$@" >>"$LOGS/$name.log" 2>&1 &
    PIDS[$name]=$!
    ORDER+=("$name")
  }
  start_own recorder -p "output:=$OUT" \
    -p "topics:=[/joint_states,/mujoco_driver/true_joint_states,/effort_controller/commands,/controller/controller_state,/diagnostics,/robot_description]" \
    -p "actions:=[/controller/follow_joint_trajectory]"
  start_own mujoco_driver -p "robot:=$STAND_IN" "${RATE_PARAM[@]}" ${REALISM:+-p "realism:=$REALISM"} \
    "${DRIVER_EXTRA[@]}"
  start_own controller "${FILES[@]}" -p "robot:=$STAND_IN" -p "type:=$CONTROLLER" -p mode:=realtime \
    "${RATE_PARAM[@]}" "${EXTRA[@]}"
  START=$SECONDS
  FAILED=()
  declare -A CODES=()
  echo "run_experiment.sh: the MuJoCo $STAND_IN and the $CONTROLLER controller recorded to $OUT (domain $ROS_DOMAIN_ID); send goals to /controller/follow_joint_trajectory${RUN_SECONDS:+ for $RUN_SECONDS s}, Ctrl-C to stop"
  while :; do
    for name in "${ORDER[@]}"; do
      if ! kill -0 "${PIDS[$name]}" 2>/dev/null; then
        wait "${PIDS[$name]}"; code=$(outcome "$name" $?)
        CODES[$name]=$code
        [[ "$code" -ne 0 ]] && { FAILED+=("$name"); explain "$name" "$code"; }
      fi
    done
    [[ ${#CODES[@]} -gt 0 ]] && break
    [[ -n "$RUN_SECONDS" ]] && (( SECONDS - START >= RUN_SECONDS )) && break
    if (( SECONDS - START > TIMEOUT )); then echo "run_experiment.sh: timeout after ${TIMEOUT} s; stopping nodes" >&2; break; fi
    sleep 0.1
  done
  stop_all
  for name in "${ORDER[@]}"; do
    [[ -n "${CODES[$name]:-}" ]] && continue
    wait "${PIDS[$name]}" 2>/dev/null; CODES[$name]=$(outcome "$name" $?)
    [[ "${CODES[$name]}" -ne 0 ]] && { FAILED+=("$name"); explain "$name" "${CODES[$name]}"; }
  done
  if [[ ${#FAILED[@]} -gt 0 ]]; then
    echo "run_experiment.sh: failed nodes: ${FAILED[*]} (logs in $LOGS/)" >&2
    exit 1
  fi
  echo "run_experiment.sh: the stand-in run is recorded to $OUT in $((SECONDS - START)) s (pdsmc analyze $OUT)"
  exit 0
fi

for name in "${NODE_NAMES[@]}"; do
  proc="$name"
  [[ -n "${IN_GROUP[$name]:-}" ]] && proc=composed
  [[ -n "${PIDS[$proc]:-}" ]] && continue  # the composed process is already started
  [[ "$MODE" == realtime && "$name" == plant ]] && wait_for_loops
  ORDER+=("$proc")
  if [[ "$name" == recorder || ( "$proc" == composed && -n "${IN_GROUP[recorder]:-}" ) ]]; then
    start_node "$proc" -p "output:=$OUT"
  else
    start_node "$proc"
  fi
done
if [[ "$VIEWER" == 1 ]]; then
  ORDER+=(viewer)
  start_node viewer -p "port:=$VIEWER_PORT"
fi

START=$SECONDS
declare -A CODES=()
FAILED=()
while :; do
  running=0
  for name in "${ORDER[@]}"; do
    [[ -n "${CODES[$name]:-}" ]] && continue
    pid="${PIDS[$name]}"
    if kill -0 "$pid" 2>/dev/null; then
      running=$((running + 1))
    else
      wait "$pid"; code=$(outcome "$name" $?)
      if [[ $code -ne 0 && -n "${RESPAWN[$name]:-}" && "${RESPAWN[$name]}" -lt $RESPAWN_MAX ]] \
          && kill -0 "${PIDS[$PLANT_PROC]}" 2>/dev/null; then
        RESPAWN[$name]=$(( RESPAWN[$name] + 1 ))
        echo "run_experiment.sh: node '$name' died (exit $code); respawning in ${RESPAWN_DELAY} s (${RESPAWN[$name]} of $RESPAWN_MAX)" >&2
        sleep "$RESPAWN_DELAY"
        start_node "$name"
        running=$((running + 1))
        continue
      fi
      CODES[$name]=$code
      if [[ "${CODES[$name]}" -ne 0 ]]; then
        FAILED+=("$name")
        explain "$name" "$code"
      fi
    fi
  done
  [[ $running -eq 0 ]] && break
  # real time: once the plant has finished the motion, give the others a moment, then
  # stop them (recorder last) -- they cannot know the plant's last message was its last
  if [[ "$MODE" == realtime && ${#ORDER[@]} -gt 1 && "${CODES[$PLANT_PROC]:-}" == 0 ]]; then
    PLANT_DONE="${PLANT_DONE:-$SECONDS}"
    if (( SECONDS - PLANT_DONE >= 5 )); then
      stop_all
      # a node stopped by SIGINT after the motion exits 0; anything else is a failure
      for name in "${ORDER[@]}"; do
        [[ -z "${CODES[$name]:-}" ]] || continue
        wait "${PIDS[$name]}" 2>/dev/null; CODES[$name]=$(outcome "$name" $?)
        if [[ "${CODES[$name]}" -ne 0 ]]; then FAILED+=("$name"); explain "$name" "${CODES[$name]}"; fi
      done
      break
    fi
  fi
  if [[ ${#FAILED[@]} -gt 0 && $KEEP_GOING -eq 0 ]]; then
    FAIL_AT="${FAIL_AT:-$SECONDS}"
    if (( SECONDS - FAIL_AT < 3 )); then sleep 0.05; continue; fi
    stop_all
    for name in "${ORDER[@]}"; do [[ -n "${CODES[$name]:-}" ]] || { wait "${PIDS[$name]}" 2>/dev/null; CODES[$name]=$(outcome "$name" $?); }; done
    break
  fi
  if (( SECONDS - START > TIMEOUT )); then
    echo "run_experiment.sh: timeout after ${TIMEOUT} s; stopping nodes" >&2
    stop_all
    for name in "${ORDER[@]}"; do [[ -n "${CODES[$name]:-}" ]] || { wait "${PIDS[$name]}" 2>/dev/null; CODES[$name]=$(outcome "$name" $?); }; done
    exit 1
  fi
  sleep 0.05
done

# a diverged arm (non-finite or runaway state: the plant stops with an error) fails the run
DIVERGED="$(grep -h -o -m 1 'diverged at t = .*' "$LOGS/plant.log" "$LOGS/composed.log" 2>/dev/null | head -n 1)"
[[ -n "$DIVERGED" ]] && echo "run_experiment.sh: the run $DIVERGED" >&2
if [[ ${#FAILED[@]} -gt 0 || -n "$DIVERGED" ]]; then
  echo "run_experiment.sh: failed nodes: ${FAILED[*]:-none} (logs in $LOGS/)" >&2
  exit 1
fi
echo "run_experiment.sh: $ROBOT/$CONTOUR/$CONTROLLER ($MODE) recorded to $OUT in $((SECONDS - START)) s"
