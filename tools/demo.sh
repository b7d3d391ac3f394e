#!/usr/bin/env bash
# The main job: the estimator node over Cyclone DDS fed by a simulated controller.
# Usage: bash tools/demo.sh [glpma-fk demo options, e.g. --manipulator hexapod --duration 20]
source "$(dirname "$0")/env.sh" "tools"
exec glpma-fk demo "$@"
