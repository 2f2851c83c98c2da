#!/bin/sh
# The checks run inside the SocketCAN test VM (as /vmtest.sh; busybox sh). Each prints
# `VMTEST PASS NAME` or `VMTEST FAIL NAME: WHY`, with what the tools printed indented by `  | `;
# the last line is `VMTEST DONE passed=N failed=M`. crates/buslab/tests/vm_socketcan.rs reads
# them from the serial console.
#
# Waits are for events (a line in a file), looked for every 0.1 s for at most 10 minutes, never
# a fixed sleep: the VM is emulated (TCG) and runs at nice 19, so a loaded host slows it down
# twentyfold and more (the test outside bounds the whole run by the VM's CPU time).

pass=0
fail=0
ok() {
    echo "VMTEST PASS $1"
    pass=$((pass + 1))
}
bad() {
    echo "VMTEST FAIL $1: $2"
    fail=$((fail + 1))
}
show() {
    for f in "$@"; do
        [ -s "$f" ] && sed "s#^#  | $(basename "$f"): #" "$f"
    done
}
# wait_for FILE TEXT [COMMAND]: until FILE contains TEXT, running COMMAND between looks.
# Looks 0.1 s apart at first, then further apart (up to 0.8 s): each look forks, which costs
# the emulated guest CPU time, and on a starved host a wait lasts long in wall time, so a
# fixed pace would make the VM's work grow with the host's load (the test bounds that work).
# A wait past 30 s (and every minute after) prints the guest's busiest processes, so the
# console says what the guest was doing if the host gives up on it.
wait_for() {
    waited=0
    pause=100000
    report=30000000
    while ! grep -qF -- "$2" "$1" 2>/dev/null; do
        [ -n "${3:-}" ] && eval "$3" >/dev/null 2>&1
        [ "$waited" -ge 600000000 ] && return 1
        usleep "$pause"
        waited=$((waited + pause))
        [ "$pause" -lt 800000 ] && pause=$((pause * 2))
        if [ "$waited" -ge "$report" ]; then
            report=$((report + 60000000))
            echo "  ! still waiting for '$2' in $1 after $((waited / 1000000)) s; busiest (CPU ticks, pid, name):"
            busiest | sed 's/^/  !   /'
        fi
    done
    return 0
}
# busiest: the five processes that used the most CPU time so far (utime + stime in ticks).
busiest() {
    for stat in /proc/[0-9]*/stat; do
        read -r line <"$stat" 2>/dev/null || continue
        name=${line#*(}
        name=${name%%)*}
        # After the name: state ppid pgrp session tty tpgid flags minflt cminflt majflt
        # cmajflt utime stime ...
        set -- ${line##*) }
        echo "$((${12} + ${13})) ${line%% *} $name"
    done | sort -rn | head -5
}
# count FILE TEXT: lines of FILE containing TEXT.
count() {
    grep -cF -- "$2" "$1" 2>/dev/null || true
}

# 1. cansend on vcan0 -> buslab dump socketcan:vcan0
buslab -v dump socketcan:vcan0 >/tmp/dump1 2>/tmp/dump1.err &
dump1=$!
if wait_for /tmp/dump1.err "dump: listening"; then
    cansend vcan0 123#1122
    cansend vcan0 12345678#DEAD
    if wait_for /tmp/dump1 "DE AD" &&
        grep -qxF "  vcan0  123   [2]  11 22" /tmp/dump1 &&
        grep -qxF "  vcan0  12345678   [2]  DE AD" /tmp/dump1; then
        ok cansend-to-buslab-dump
    else
        bad cansend-to-buslab-dump "buslab dump did not show both frames"
    fi
else
    bad cansend-to-buslab-dump "buslab dump did not start"
fi
show /tmp/dump1 /tmp/dump1.err
kill $dump1 2>/dev/null

# 1b. An error frame (cansend can write one) decoded by buslab dump -e, in candump's words.
buslab -v dump -e socketcan:vcan0 >/tmp/dump1e 2>/tmp/dump1e.err &
dump1e=$!
if wait_for /tmp/dump1e.err "dump: listening"; then
    cansend vcan0 20000004#0004000000000000
    if wait_for /tmp/dump1e "controller-problem{rx-error-warning}" &&
        grep -qF "  vcan0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME" /tmp/dump1e; then
        ok error-frame-decoded
    else
        bad error-frame-decoded "buslab dump -e did not decode the error frame"
    fi
else
    bad error-frame-decoded "buslab dump -e did not start"
fi
show /tmp/dump1e
kill $dump1e 2>/dev/null

# 2. buslab send socketcan:vcan0 -> candump
candump -L vcan0 >/tmp/candump2 2>&1 &
candump2=$!
if wait_for /tmp/candump2 "7FF#" "cansend vcan0 7FF#"; then
    buslab send socketcan:vcan0 321#AABB 00000456#DEAD 7FF#R3 2>/tmp/send2.err
    if wait_for /tmp/candump2 "vcan0 7FF#R" &&
        grep -qF "vcan0 321#AABB" /tmp/candump2 &&
        grep -qF "vcan0 00000456#DEAD" /tmp/candump2; then
        ok buslab-send-to-candump
    else
        bad buslab-send-to-candump "candump did not show buslab's frames"
    fi
else
    bad buslab-send-to-candump "candump saw no probe frame"
fi
kill $candump2 2>/dev/null
show /tmp/candump2 /tmp/send2.err

# 3. buslab bridge between a virtual bus (buslab bus serve) and vcan0. A node on the
#    virtual bus (buslab dump, -L) acknowledges frames there and shows what crossed.
buslab bus serve >/tmp/serve3 2>/tmp/serve3.err &
serve3=$!
wait_for /tmp/serve3 "socketcand://" || bad bridge "bus serve did not start"
buslab -v dump vcan0 -L >/tmp/vdump3 2>/tmp/vdump3.err &
vdump3=$!
wait_for /tmp/vdump3.err "dump: listening" || bad bridge "dump on the virtual bus did not start"
buslab -v bridge vcan0 socketcan:vcan0 2>/tmp/bridge3.err &
bridge3=$!
candump -L vcan0 >/tmp/candump3 2>&1 &
candump3=$!
if wait_for /tmp/bridge3.err "bridge: socketcand://" &&
    wait_for /tmp/candump3 "7FF#" "cansend vcan0 7FF#"; then
    # virtual -> vcan0, through the pump of socketcan:vcan0: it waits for vcan0 with no
    # timeout, and nothing comes on vcan0 meanwhile, so only its wake line sends the frame.
    buslab send vcan0 321#AB 2>/tmp/send3.err
    wait_for /tmp/candump3 "vcan0 321#AB" && to_vcan=yes || to_vcan=no
    # vcan0 -> virtual
    cansend vcan0 654#CD
    wait_for /tmp/vdump3 "vcan0 654#CD" && to_virtual=yes || to_virtual=no
    # No echo: a sentinel from vcan0 arrives after anything the first frame could have
    # caused, and each frame is on each bus once.
    cansend vcan0 111#
    wait_for /tmp/vdump3 "vcan0 111#"
    if [ "$to_vcan" = yes ] && [ "$to_virtual" = yes ] &&
        [ "$(count /tmp/vdump3 '321#AB')" = 1 ] && [ "$(count /tmp/candump3 '321#AB')" = 1 ] &&
        [ "$(count /tmp/vdump3 '654#CD')" = 1 ] && [ "$(count /tmp/candump3 '654#CD')" = 1 ]; then
        ok bridge-virtual-bus-and-vcan0
    else
        bad bridge-virtual-bus-and-vcan0 "to vcan0: $to_vcan, to the virtual bus: $to_virtual (or a frame twice)"
    fi
    # Frames to vcan0 are sent when they come, not after a read timeout.
    if grep -qF "a job wakes the wait for SocketCAN interface vcan0" /tmp/bridge3.err; then
        ok bridge-pump-woken-for-vcan0
    else
        bad bridge-pump-woken-for-vcan0 "the pump of socketcan:vcan0 cannot be woken"
    fi
else
    bad bridge-virtual-bus-and-vcan0 "the bridge did not start"
fi
kill $candump3 2>/dev/null
show /tmp/candump3 /tmp/vdump3 /tmp/bridge3.err /tmp/send3.err

# 4. An SLCAN adapter served by buslab on the virtual bus, attached with slcand as slcan0.
buslab slcan serve --bus vcan0 --link /tmp/ttySL0 >/tmp/slcan4 2>/tmp/slcan4.err &
slcan4=$!
if wait_for /tmp/slcan4 "/tmp/ttySL0"; then
    slcand -o -c -s6 -F "$(readlink /tmp/ttySL0)" slcan0 2>/tmp/slcand4.err &
    slcand4=$!
    i=0
    while [ ! -e /sys/class/net/slcan0 ] && [ $i -lt 600 ]; do
        i=$((i + 1))
        usleep 100000
    done
    ip link set up slcan0 2>>/tmp/slcand4.err
    candump -L slcan0 >/tmp/candump4 2>&1 &
    candump4=$!
    if wait_for /tmp/candump4 "slcan0 7FF#" "buslab send vcan0 7FF#"; then
        buslab send vcan0 5A5#0102 12345678#R2 2>/tmp/send4.err
        if wait_for /tmp/candump4 "slcan0 12345678#R" &&
            grep -qF "slcan0 5A5#0102" /tmp/candump4; then
            ok slcand-slcan0-candump
        else
            bad slcand-slcan0-candump "candump on slcan0 did not show the virtual bus's frames"
        fi
        cansend slcan0 3C3#AA
        if wait_for /tmp/vdump3 "vcan0 3C3#AA"; then
            ok cansend-slcan0-to-virtual-bus
        else
            bad cansend-slcan0-to-virtual-bus "the virtual bus did not get cansend's frame"
        fi
    else
        bad slcand-slcan0-candump "no frame reached candump on slcan0"
    fi
    kill $candump4 $slcand4 2>/dev/null
    show /tmp/candump4 /tmp/slcand4.err /tmp/send4.err
else
    bad slcand-slcan0-candump "buslab slcan serve did not start"
fi
show /tmp/slcan4.err
kill $slcan4 $bridge3 $vdump3 $serve3 2>/dev/null

# 5. CAN FD: vcan1 and vcan2 with MTU 72 carry FD frames (vcan's default, as vcan0's), vcan3
#    with MTU 16 does not (a classic controller's, or a vcan made classic).
for fdif in vcan1:72 vcan2:72 vcan3:16; do
    ip link add dev ${fdif%:*} type vcan && ip link set ${fdif%:*} mtu ${fdif#*:} &&
        ip link set up ${fdif%:*} || echo "  | could not make ${fdif%:*} with MTU ${fdif#*:}"
done
long64=$(i=0; while [ $i -lt 64 ]; do printf '%02X' $i; i=$((i + 1)); done)

# 5a. cansend's FD frames -> buslab dump -L socketcan:vcan1 (flags as python-can writes them).
buslab -v dump -L socketcan:vcan1 >/tmp/dump5 2>/tmp/dump5.err &
dump5=$!
if wait_for /tmp/dump5.err "dump: listening"; then
    cansend vcan1 123##1112233445566778899AABBCC
    cansend vcan1 1ABCDEF0##2$long64
    cansend vcan1 321#AB
    if wait_for /tmp/dump5 "vcan1 321#AB" &&
        grep -qF "vcan1 123##1112233445566778899AABBCC" /tmp/dump5 &&
        grep -qF "vcan1 1ABCDEF0##2$long64" /tmp/dump5; then
        ok fd-cansend-to-buslab-dump
    else
        bad fd-cansend-to-buslab-dump "buslab dump -L did not show the FD frames"
    fi
else
    bad fd-cansend-to-buslab-dump "buslab dump did not start"
fi
kill $dump5 2>/dev/null
show /tmp/dump5 /tmp/dump5.err

# 5b. buslab bridge between two FD interfaces, both ways, with can-utils on each side.
#     Frames buslab writes carry FDF (0x4) as newer kernels mark FD frames: candump 2020.11
#     prints the whole flags nibble, so BRS shows as 1 or 5 and ESI as 2 or 6.
candump -L vcan2 >/tmp/candump5b2 2>&1 &
c5b2=$!
candump -L vcan1 >/tmp/candump5b1 2>&1 &
c5b1=$!
buslab -v bridge socketcan:vcan1 socketcan:vcan2 2>/tmp/bridge5b.err &
bridge5b=$!
if wait_for /tmp/bridge5b.err "CAN FD both ways" &&
    wait_for /tmp/candump5b2 "vcan2 7FF#" "cansend vcan1 7FF#"; then
    cansend vcan1 123##1112233445566778899AABBCC
    cansend vcan1 1ABCDEF0##0$long64
    wait_for /tmp/candump5b2 "vcan2 1ABCDEF0##" && to_vcan2=yes || to_vcan2=no
    cansend vcan2 00000321##2CAFE
    wait_for /tmp/candump5b1 "vcan1 00000321##" && to_vcan1=yes || to_vcan1=no
    if [ "$to_vcan2" = yes ] && [ "$to_vcan1" = yes ] &&
        grep -qE "vcan2 123##[15]112233445566778899AABBCC$" /tmp/candump5b2 &&
        grep -qE "vcan2 1ABCDEF0##[04]$long64$" /tmp/candump5b2 &&
        grep -qE "vcan1 00000321##[26]CAFE$" /tmp/candump5b1 &&
        [ "$(count /tmp/candump5b1 '123##')" = 1 ]; then
        ok fd-bridge-vcan1-vcan2
    else
        bad fd-bridge-vcan1-vcan2 "to vcan2: $to_vcan2, to vcan1: $to_vcan1 (or a frame changed or echoed)"
    fi
else
    bad fd-bridge-vcan1-vcan2 "the bridge did not start"
fi
kill $bridge5b $c5b1 $c5b2 2>/dev/null
show /tmp/candump5b1 /tmp/candump5b2 /tmp/bridge5b.err

# 5c. An FD interface bridged to a classic one (MTU 16): classic frames cross, FD frames are
#     counted with the reason said once, and the count is shown when the bridge stops.
candump -L vcan3 >/tmp/candump5c 2>&1 &
c5c=$!
buslab -v bridge socketcan:vcan1 socketcan:vcan3 2>/tmp/bridge5c.err &
bridge5c=$!
if wait_for /tmp/bridge5c.err "CAN FD one way" &&
    wait_for /tmp/candump5c "vcan3 7FF#" "cansend vcan1 7FF#"; then
    cansend vcan1 123##1AABB
    cansend vcan1 124##0CC
    cansend vcan1 125#DD
    wait_for /tmp/candump5c "vcan3 125#DD"
    kill -INT $bridge5c
    wait $bridge5c
    if wait_for /tmp/bridge5c.err "stopped" &&
        [ "$(count /tmp/bridge5c.err 'are not bridged: socketcan:vcan3 is classic CAN: interface vcan3 has MTU 16')" = 1 ] &&
        grep -qF "2 CAN FD frames were not bridged" /tmp/bridge5c.err &&
        [ "$(count /tmp/candump5c '##')" = 0 ]; then
        ok fd-to-a-classic-interface-counted
    else
        bad fd-to-a-classic-interface-counted "the FD frames were not refused once and counted"
    fi
else
    bad fd-to-a-classic-interface-counted "the bridge did not start"
fi
kill $c5c 2>/dev/null
show /tmp/candump5c /tmp/bridge5c.err

echo "VMTEST DONE passed=$pass failed=$fail"
