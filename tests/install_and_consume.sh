#!/usr/bin/env bash
# The install as a user gets it: `cmake --install` into a temporary prefix, then, from a folder
# outside the source and build trees:
#   - the installed probecast-bake bakes a scene whose sidecar only the install holds
#     (share/probecast/sidecars/rtxgi-cornell.json: 729 probes) to the build tree's probe count
#     and says which sidecar it took; copied without its data it stops, naming the sidecar it
#     lacks, and with the data under $PROBECAST_DATA it finds it again;
#   - the installed tools load their SPIR-V from share/probecast/shaders: a bake on the Vulkan
#     backend and one headless client frame (skipped where no Vulkan device is found);
#   - a consumer project (tests/install/consumer) built with find_package(probecast), and the
#     same source built with pkg-config alone, reads the baked file and holds the installed
#     probecast-server's field over TLS with a token from the installed probecast-token; it
#     needs neither GLFW nor Vulkan (ldd); the installed probecast-loadgen connects with
#     --connect HOST:PORT and with the older --host/--port.
#   tests/install_and_consume.sh SOURCE-DIR BUILD-DIR WORK-DIR    (CTest: install_and_consume)
set -uo pipefail
src=$(realpath "$1")
build=$(realpath "$2")
work=$3
rm -rf "$work" && mkdir -p "$work" && work=$(realpath "$work") && cd "$work" || exit 1

failures=0
fail() {
  echo "install_and_consume: FAIL: $*" >&2
  failures=$((failures + 1))
}
# run LOG CMD...: runs CMD with stdout and stderr in LOG; on failure shows the log and stops.
run() {
  local log=$1
  shift
  if ! "$@" >"$log" 2>&1; then
    sed 's/^/  | /' "$log" >&2
    echo "install_and_consume: FAIL: '$*' exited non-zero" >&2
    exit 1
  fi
}
# has FILE TEXT: FILE contains TEXT.
has() { grep -qF -- "$2" "$1" || { fail "$1 lacks '$2'"; sed 's/^/  | /' "$1" >&2; }; }
probes_baked() { sed -n 's/.*baked \([0-9]*\) probes.*/\1/p' "$1" | head -n 1; }

prefix=$work/prefix
run install.log cmake --install "$build" --prefix "$prefix" --strip
for f in bin/probecast-bake bin/probecast-server share/probecast/sidecars/rtxgi-cornell.json \
  share/probecast/shaders/probe_trace.rgen.spv share/probecast/shaders/client_tonemap.frag.spv \
  include/probecast/client/net_client.h include/probecast/protocol/baked_field_generated.h \
  lib/cmake/probecast/probecastConfig.cmake; do
  [[ -e $prefix/$f ]] || fail "the install lacks $f"
done
pcfile=$(find "$prefix" -name probecast.pc | head -n 1)
[[ -n $pcfile ]] || fail "the install has no probecast.pc"

# A scene the shared sidecar names by its folder: one quad, lit only by the sidecar's sun.
mkdir -p run/rtxgi-cornell
printf 'v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\nf 1 4 3\n' >run/rtxgi-cornell/room.obj
cd run || exit 1
bake=(--scene rtxgi-cornell/room.obj --updates 1 --rays 16)
run bake_tree.log "$build/bin/probecast-bake" "${bake[@]}" --output tree.probes
run bake_installed.log "$prefix/bin/probecast-bake" "${bake[@]}" --output field.probes
has bake_installed.log "sidecar $prefix/share/probecast/sidecars/rtxgi-cornell.json"
tree=$(probes_baked bake_tree.log)
installed=$(probes_baked bake_installed.log)
[[ $installed == 729 && $installed == "$tree" ]] ||
  fail "the installed bake made '$installed' probes, the build tree's '$tree' (the sidecar: 729)"

# The executable copied without its data: the scene's own sidecar is missing, which stops the
# bake (exit 1, naming it) rather than baking the scene without its lights and volumes.
mkdir -p "$work/moved"
cp "$prefix/bin/probecast-bake" "$work/moved/"
rc=0
"$work/moved/probecast-bake" "${bake[@]}" --output lost.probes >bake_lost.log 2>&1 || rc=$?
[[ $rc == 1 && ! -e lost.probes ]] || fail "the bake without its sidecar exited $rc"
has bake_lost.log "its sidecar rtxgi-cornell.json (one of probecast's own) is in none of"
# $PROBECAST_DATA then finds the data.
cp -r "$prefix/share/probecast" "$work/moved/data"
PROBECAST_DATA=$work/moved/data run bake_moved.log "$work/moved/probecast-bake" "${bake[@]}" \
  --out moved.probes
has bake_moved.log "sidecar $work/moved/data/sidecars/rtxgi-cornell.json"

# The SPIR-V, from the install: the GPU tracer's and the client renderer's.
rc=0
"$prefix/bin/probecast-bake" --backend vulkan --updates 1 --rays 16 --output vulkan.probes \
  >bake_vulkan.log 2>&1 || rc=$?
if grep -q "no Vulkan" bake_vulkan.log; then
  echo "install_and_consume: no Vulkan device: the installed shaders are not loaded"
else
  [[ $rc == 0 ]] || { fail "the installed bake on the Vulkan backend exited $rc"; cat bake_vulkan.log >&2; }
  rc=0
  "$prefix/bin/probecast-client" --scene rtxgi-cornell/room.obj --probes field.probes --width 32 --height 24 \
    --msaa 2 --out frames >client.log 2>&1 || rc=$?
  [[ $rc == 0 && -f frames/frame_0000.png ]] ||
    { fail "the installed client exited $rc"; cat client.log >&2; }
fi

# The consumer, built against the install both ways.
run cmake_configure.log cmake -S "$src/tests/install/consumer" -B consumer-cmake -G Ninja \
  -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release
run cmake_build.log cmake --build consumer-cmake
export PKG_CONFIG_PATH=$(dirname "$pcfile")
# shellcheck disable=SC2046 # pkg-config's words are flags
run pkgconfig_build.log c++ -std=c++20 -O1 -o consumer-pkgconfig \
  "$src/tests/install/consumer/consumer.cpp" $(pkg-config --cflags --libs probecast)
for consumer in consumer-cmake/consumer ./consumer-pkgconfig; do
  if ldd "$consumer" | grep -E 'libglfw|libvulkan' >&2; then
    fail "$consumer needs GLFW or Vulkan (ldd above)"
  fi
done

# The installed server, with a token issuer of this run.
tok=$prefix/bin/probecast-token
run keygen.log "$tok" keygen --signing-key issuer.key --verify-key issuer.pub
run issue.log "$tok" issue --signing-key issuer.key --client consumer --ttl 1h --output consumer.token
"$prefix/bin/probecast-server" --scene rtxgi-cornell/room.obj --probes field.probes --rays 16 --rate 2 \
  --bind 127.0.0.1 --port 0 --token-key issuer.pub --dev-self-signed --duration 120 \
  >server.out 2>server.log &
server=$!
trap 'kill $server 2>/dev/null' EXIT
port=
for _ in $(seq 1 300); do
  port=$(sed -n 's/^ready port \([0-9]*\)$/\1/p' server.out)
  [[ -n $port ]] && break
  kill -0 $server 2>/dev/null || break
  sleep 0.1
done
fingerprint=$(sed -n 's/^tls-fingerprint \(.*\)$/\1/p' server.out)
if [[ -z $port || -z $fingerprint ]]; then
  sed 's/^/  | /' server.log >&2
  fail "the installed server did not start"
else
  for consumer in consumer-cmake/consumer ./consumer-pkgconfig; do
    log=$(basename "$consumer").log
    rc=0
    "$consumer" field.probes 127.0.0.1 "$port" consumer.token "$fingerprint" >"$log" 2>&1 || rc=$?
    sed "s|^|$consumer: |" "$log"
    [[ $rc == 0 ]] || fail "$consumer exited $rc"
    has "$log" "baked: $installed probes"
    has "$log" ", $installed probes, version"
  done
  # The installed load generator names the server as the client does (--connect), and still
  # takes the older --host/--port. What is checked is that its client joined and received
  # bricks without errors; whether one second on a loaded machine counts as starved (its exit
  # code 2) is the load tests' business.
  loadgen_runs() {
    local log=$1 rc=0
    shift
    "$prefix/bin/probecast-loadgen" "$@" --token-file consumer.token \
      --server-fingerprint "$fingerprint" --clients 1 --ramp 0 --warmup 0 --seconds 1 \
      >"$log" 2>&1 || rc=$?
    if [[ $rc != 0 && $rc != 2 ]] || ! grep -q "^errors 0," "$log" ||
      ! grep -qE "^bricks applied [1-9]" "$log"; then
      fail "probecast-loadgen $* exited $rc, or its client received nothing"
      sed 's/^/  | /' "$log" >&2
    fi
  }
  loadgen_runs loadgen.log --connect "127.0.0.1:$port"
  loadgen_runs loadgen_old_flags.log --host 127.0.0.1 --port "$port"
fi

if ((failures > 0)); then
  echo "install_and_consume: $failures check(s) failed (logs in $work/run)" >&2
  exit 1
fi
echo "install_and_consume: installed into $prefix; bake $installed probes as in the tree; consumers held the stream"
