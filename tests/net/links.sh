#!/bin/bash
# Real bottlenecks: a probecast-server in a network namespace, clients in another, joined by
# veth pairs whose server ends are rate-limited by the kernel's tbf qdisc (a drop-tail queue
# of 100 ms at the rate). First three clients, each behind its own link (0.5, 2, 10 Mbit/s);
# then three clients sharing one 2 Mbit/s link. Checks what each client received against its
# link, that no slow client slows the others, and that the links dropped few datagrams
# (congestion control: without it a link of 0.5 Mbit/s dropped most of what the server sent).
# Needs root and the iproute2 and jq packages; exits 77 (skipped) where they or namespaces are
# missing. The CTest `net_links`.
# Usage: links.sh BUILD_DIR
set -u
build=${1:?usage: links.sh BUILD_DIR}
server="$build/bin/probecast-server"
loadgen="$build/bin/probecast-loadgen"
tag=pc$$
work=$(mktemp -d)
skip() { echo "net links: skipped: $*"; exit 77; }
[ "$(id -u)" = 0 ] || skip "needs root for network namespaces"
command -v ip >/dev/null && command -v tc >/dev/null && command -v jq >/dev/null || skip "needs ip, tc and jq"
cleanup() {
  ip netns pids "${tag}s" 2>/dev/null | xargs -r kill 2>/dev/null
  ip netns pids "${tag}c" 2>/dev/null | xargs -r kill 2>/dev/null
  ip netns del "${tag}s" 2>/dev/null
  ip netns del "${tag}c" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
ip netns add "${tag}s" 2>/dev/null || skip "cannot create a network namespace"
ip netns add "${tag}c" || skip "cannot create a second network namespace"
S() { ip netns exec "${tag}s" "$@"; }
C() { ip netns exec "${tag}c" "$@"; }
S ip link set lo up
C ip link set lo up
# Link i: server 10.77.i.1 <-> client 10.77.i.2, tbf on the server's end (what it sends).
link() {
  local i=$1 mbit=$2
  ip link add "${tag}s$i" type veth peer name "${tag}c$i" || skip "cannot create veth pairs"
  ip link set "${tag}s$i" netns "${tag}s"
  ip link set "${tag}c$i" netns "${tag}c"
  S ip addr add "10.77.$i.1/24" dev "${tag}s$i"
  C ip addr add "10.77.$i.2/24" dev "${tag}c$i"
  S ip link set "${tag}s$i" up
  C ip link set "${tag}c$i" up
  S tc qdisc add dev "${tag}s$i" root tbf rate "${mbit}mbit" burst 4kb latency 100ms ||
    skip "tbf not available"
}
link 1 0.5
link 2 2
link 3 10

# A token issuer for this run; the server makes its own certificate, the clients pin it.
"$build/bin/probecast-token" keygen --signing-key "$work/issuer.key" --verify-key "$work/issuer.pub"
"$build/bin/probecast-token" issue --signing-key "$work/issuer.key" --client links \
  --output "$work/links.token"
S "$server" --scene builtin --bind 0.0.0.0 --port 7471 --token-key "$work/issuer.pub" \
  --dev-self-signed --rays 16 --rate 10 \
  --warmup 2 --max-clients 16 --stats-interval 0 --metrics-port 0 >"$work/server.log" 2>&1 &
for _ in $(seq 100); do
  grep -q "^ready port" "$work/server.log" 2>/dev/null && break
  sleep 0.2
done
grep -q "^ready port" "$work/server.log" || { cat "$work/server.log"; echo "net links: server did not start"; exit 1; }
fingerprint=$(sed -n 's/^tls-fingerprint \(.*\)$/\1/p' "$work/server.log")
auth=(--token-file "$work/links.token" --server-fingerprint "$fingerprint")

fail=0
check() { # description, condition (jq on the report)
  if ! jq -e "$2" "$3" >/dev/null; then
    echo "FAIL: $1"
    fail=1
  else
    echo "ok: $1"
  fi
}

# Three clients, one per link, at the same time.
for i in 1 2 3; do
  C "$loadgen" --host "10.77.$i.1" --port 7471 "${auth[@]}" --clients 1 --warmup 3 --seconds 8 \
    --min-held-psnr 0 --max-change-age 1e9 --json "$work/link$i.json" >"$work/link$i.log" 2>&1 &
done
wait $(jobs -p | tail -3)
for i in 1 2 3; do
  mbit=$(S tc qdisc show dev "${tag}s$i" | grep -o 'rate [0-9.]*[KMG]*bit' | head -1)
  sent=$(S tc -s qdisc show dev "${tag}s$i" | grep -o 'Sent [0-9]* bytes [0-9]* pkt' | awk '{print $4}')
  dropped=$(S tc -s qdisc show dev "${tag}s$i" | grep -o 'dropped [0-9]*' | awk '{print $2}')
  echo "link $i ($mbit): $(jq -r '.clients[0] | "received \(.kbit_down|floor) kbit/s, sync \(.sync_s) s, rate \(.rate_mbit) Mbit/s, held \(.held_psnr_db) dB, oldest change p95 \(.oldest_change_s_p95) s, level \(.quality_level)"' "$work/link$i.json"), qdisc sent $sent packets, dropped $dropped"
  check "link $i: no errors, never starved" '.errors == 0 and .starved_clients == 0' "$work/link$i.json"
  echo "$sent $dropped" >"$work/drops$i"
done
check "0.5 Mbit/s: received at most the link's rate" '.clients[0].kbit_down <= 520' "$work/link1.json"
check "2 Mbit/s: received at most the link's rate" '.clients[0].kbit_down <= 2080' "$work/link2.json"
# The field needs less than the fast link carries, so what it received says little; that its
# sender's rate stayed above the slow links' and it was sent every change at full precision says
# that they did not hold it back.
check "10 Mbit/s: the slow links did not slow it (sender's rate over 2 Mbit/s, full precision)" \
  '.clients[0].rate_mbit > 2 and .clients[0].quality_level < 0.5' "$work/link3.json"
for i in 1 2 3; do
  read -r sent dropped <"$work/drops$i"
  share=$(awk -v s="$sent" -v d="$dropped" 'BEGIN { printf "%.4f", (s + d > 0) ? d / (s + d) : 0 }')
  if awk -v x="$share" 'BEGIN { exit !(x < 0.05) }'; then echo "ok: link $i dropped $share of its packets"
  else echo "FAIL: link $i dropped $share of its packets (more than 5%)"; fail=1; fi
done

# Three clients sharing the 2 Mbit/s link.
S tc qdisc del dev "${tag}s2" root
S tc qdisc add dev "${tag}s2" root tbf rate 2mbit burst 4kb latency 100ms
C "$loadgen" --host 10.77.2.1 --port 7471 "${auth[@]}" --clients 3 --ramp 2 --warmup 4 --seconds 10 \
  --min-held-psnr 0 --max-change-age 1e9 --json "$work/shared.json" >"$work/shared.log" 2>&1
sent=$(S tc -s qdisc show dev "${tag}s2" | grep -o 'Sent [0-9]* bytes [0-9]* pkt' | awk '{print $4}')
dropped=$(S tc -s qdisc show dev "${tag}s2" | grep -o 'dropped [0-9]*' | awk '{print $2}')
echo "shared 2 Mbit/s: $(jq -r '[.clients[].kbit_down|floor] | "received \(.) kbit/s"' "$work/shared.json"), qdisc sent $sent, dropped $dropped"
check "shared: no errors, never starved" '.errors == 0 and .starved_clients == 0' "$work/shared.json"
check "shared: fair (Jain index of what each received >= 0.8)" \
  '[.clients[].kbit_down] as $x | (($x|add) * ($x|add)) / (($x|length) * ([$x[] | . * .]|add)) >= 0.8' \
  "$work/shared.json"
share=$(awk -v s="$sent" -v d="$dropped" 'BEGIN { printf "%.4f", (s + d > 0) ? d / (s + d) : 0 }')
if awk -v x="$share" 'BEGIN { exit !(x < 0.05) }'; then echo "ok: shared link dropped $share of its packets"
else echo "FAIL: shared link dropped $share of its packets (more than 5%)"; fail=1; fi
[ $fail = 0 ] || { echo "--- server log tail"; tail -5 "$work/server.log"; }
exit $fail
