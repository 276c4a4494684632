#!/usr/bin/env bash
# The tools end with exit code 1 and a message naming the file and the problem when a file
# they were given cannot be used (README, Executables): a baked field with one flipped bit
# given to probecast-client and probecast-server, a scene that reaches outside its folder given
# to probecast-bake, and a missing scene given to probecast-reference; and a --connect without
# a port given to probecast-client and probecast-loadgen.
#
#   tests/tool_exit_codes.sh BIN_DIR WORK_DIR
set -uo pipefail
bin=$1
work=$2
rm -rf "$work"
mkdir -p "$work/scene"
failed=0

# expect CODE PATTERN COMMAND...: runs COMMAND, checks its exit code and that its output
# matches PATTERN (grep -E).
expect() {
  local code=$1 pattern=$2
  shift 2
  local out rc
  out=$("$@" 2>&1)
  rc=$?
  if [[ $rc -ne $code ]] || ! grep -qE -- "$pattern" <<<"$out"; then
    echo "FAIL: $(basename "$1"): exit code $rc (expected $code), output:"
    echo "$out" | tail -5
    echo "(expected a line matching: $pattern)"
    failed=1
  else
    echo "ok: $(basename "$1") exits $rc: $(grep -E -m1 -- "$pattern" <<<"$out")"
  fi
}

# A real baked field, then one bit of it flipped half way through (a probe record or an atlas).
"$bin/probecast-bake" --updates 1 --rays 16 -o "$work/field.probes" >/dev/null 2>&1 ||
  { echo "FAIL: the bake that makes the test file failed"; exit 1; }
size=$(stat -c %s "$work/field.probes")
at=$((size / 2))
byte=$(od -An -tu1 -j"$at" -N1 "$work/field.probes" | tr -d ' ')
printf "\\$(printf %03o $((byte ^ 4)))" |
  dd of="$work/field.probes" bs=1 seek="$at" conv=notrunc status=none

expect 1 "cannot use the baked field: baked file .*field.probes: checksum mismatch" \
  "$bin/probecast-client" --scene builtin --probes "$work/field.probes" --out "$work/out"
"$bin/probecast-token" keygen --signing-key "$work/issuer.key" --verify-key "$work/issuer.pub" \
  >/dev/null || { echo "FAIL: probecast-token keygen"; exit 1; }
expect 1 "baked file .*field.probes: checksum mismatch" \
  "$bin/probecast-server" --backend embree --port 0 --token-key "$work/issuer.pub" \
  --dev-self-signed --probes "$work/field.probes"

printf 'newmtl m\nKd 1 0 0\n' >"$work/outside.mtl"
printf 'mtllib ../outside.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n' \
  >"$work/scene/escape.obj"
expect 1 "escape.obj: material library '../outside.mtl' leads to .*outside the scene's folder" \
  "$bin/probecast-bake" --scene "$work/scene/escape.obj" --updates 1 -o "$work/escape.probes"
expect 1 "nope.gltf: file not found" \
  "$bin/probecast-reference" --scene "$work/scene/nope.gltf" --out "$work/ref"
# A server address without a port: a usage error before anything connects.
expect 1 "--connect: expected HOST:PORT.*, got 'localhost'" \
  "$bin/probecast-client" --scene builtin --connect localhost --out "$work/out"
expect 1 "--connect: expected HOST:PORT.*, got 'localhost'" \
  "$bin/probecast-loadgen" --connect localhost --clients 1

exit $failed
