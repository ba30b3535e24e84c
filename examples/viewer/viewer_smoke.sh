#!/bin/sh
# ctest viewer_smoke: runs fsm-viewer under Xvfb for 30 frames with the scripted probe, writes a
# screenshot (control panel included, every tetrahedral part on the continuum law, the panel's
# requests issued on a schedule) and checks the requests took and the screenshot is not blank. Exit 77 (skip) when there is no Xvfb or no GL context.
#   viewer_smoke.sh FSM_VIEWER SCREENSHOT.png
set -u
viewer=$1
png=$2
rm -f "$png"
unset WAYLAND_DISPLAY  # GLFW must use the X server we start
out=$(mktemp)
trap 'rm -f "$out"' EXIT

if command -v xvfb-run >/dev/null 2>&1; then
  log=$(mktemp)
  xvfb-run -a -s "-screen 0 1280x1024x24" \
    "$viewer" --scripted --frames 30 --screenshot "$png" --law continuum --exercise-panel \
    >"$out" 2>"$log"
  rc=$?
  cat "$log" >&2
  if grep -q "Xvfb failed to start" "$log"; then rm -f "$log"; echo "SKIP: Xvfb failed to start"; exit 77; fi
  rm -f "$log"
elif command -v Xvfb >/dev/null 2>&1; then
  # No xvfb-run: start Xvfb on the first free display ourselves.
  display=99
  while [ -e "/tmp/.X$display-lock" ] || [ -e "/tmp/.X11-unix/X$display" ]; do display=$((display + 1)); done
  Xvfb ":$display" -screen 0 1280x1024x24 -nolisten tcp >/dev/null 2>&1 &
  xvfb=$!
  trap 'kill "$xvfb" 2>/dev/null; wait "$xvfb" 2>/dev/null; rm -f "$out"' EXIT
  i=0
  while [ ! -e "/tmp/.X11-unix/X$display" ]; do
    i=$((i + 1))
    if [ $i -gt 50 ] || ! kill -0 "$xvfb" 2>/dev/null; then echo "SKIP: Xvfb failed to start"; exit 77; fi
    sleep 0.1
  done
  DISPLAY=":$display" "$viewer" --scripted --frames 30 --screenshot "$png" --law continuum \
    --exercise-panel >"$out"
  rc=$?
else
  echo "SKIP: no Xvfb (apt-get install xvfb xauth)"
  exit 77
fi

cat "$out"
if [ "$rc" -ne 0 ]; then
  [ "$rc" -eq 77 ] && echo "SKIP: no display or no OpenGL context under Xvfb"
  exit "$rc"
fi
# The scripted panel requests: integrators swapped, a law and a material set, pause, resume, reset
# (8 applied) and one material refused (E < 0) without harm.
if ! grep -q "panel: 8 requests applied, 1 refused" "$out"; then
  echo "FAIL: the panel's scripted requests were not applied as expected"
  exit 1
fi
"$viewer" --check-screenshot "$png" --min-fraction 0.05
