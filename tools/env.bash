# shellcheck shell=bash
# Enter the VEGA TVC project environment: `source tools/env.bash` (bash).
#
# Sets up what every project process needs (see docs/ENVIRONMENT_SETUP.md):
#   - the virtual environment .venv (PATH, VIRTUAL_ENV) holding the ROS 2 Jazzy wheels;
#   - AMENT_PREFIX_PATH with .venv (the wheels do not set it) and, on top, the colcon workspace
#     ros2_ws/install through colcon's own local_setup.bash (PYTHONPATH, LD_LIBRARY_PATH, ...);
#     with the argument --no-workspace the workspace is left out (used to build it);
#   - discovery on this machine only: ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, with the
#     deprecated ROS_LOCALHOST_ONLY and ROS_STATIC_PEERS unset.
# ROS_DOMAIN_ID is not chosen here: `vega`, `vega-env` and the test suite pick one per run
# (vega_bringup/rosenv.py, round robin over 1..100) unless it is already set; nodes started by hand
# (`vega node`, or an executable's path) use 101 when none is set (vega_bus/network.py), so
# nodes in several terminals meet. Export ROS_DOMAIN_ID=N (1..101) to choose another.

_vega_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd -P)"

export VIRTUAL_ENV="$_vega_root/.venv"
case ":${PATH:-}:" in
  *":$VIRTUAL_ENV/bin:"*) ;;
  *) export PATH="$VIRTUAL_ENV/bin${PATH:+:$PATH}" ;;
esac
unset PYTHONHOME

case ":${AMENT_PREFIX_PATH:-}:" in
  *":$VIRTUAL_ENV:"*) ;;
  *) export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}" ;;
esac

if [ "${1:-}" != "--no-workspace" ] && [ -f "$_vega_root/ros2_ws/install/local_setup.bash" ]; then
  # colcon's script resolves its prefix from COLCON_CURRENT_PREFIX if set: clear it first.
  unset COLCON_CURRENT_PREFIX
  # shellcheck disable=SC1091
  source "$_vega_root/ros2_ws/install/local_setup.bash"
fi

# colcon's scripts leave an empty entry (= the current directory) when the variable was unset.
if [ -n "${LD_LIBRARY_PATH:-}" ]; then
  _vega_ld=""
  IFS=: read -r -a _vega_parts <<< "$LD_LIBRARY_PATH"
  for _vega_part in "${_vega_parts[@]}"; do
    [ -n "$_vega_part" ] && _vega_ld="${_vega_ld:+$_vega_ld:}$_vega_part"
  done
  export LD_LIBRARY_PATH="$_vega_ld"
  unset _vega_ld _vega_parts _vega_part
fi

export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY ROS_STATIC_PEERS
unset _vega_root
