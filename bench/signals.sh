#!/usr/bin/env bash
# SIGINT, SIGTERM and SIGHUP stop `zelle serve` and `cpu196 serve` alike: exit 0, the state
# file or image written, no journal left, the --link symlink removed (issue 11, reliability 2).
# Usage: bash bench/signals.sh [BUSLAB]   (default: target/debug/buslab)
set -euo pipefail
# Job control: without it bash starts background jobs with SIGINT ignored.
set -m
BUSLAB=${1:-target/debug/buslab}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
for device in zelle cpu196; do
    for sig in INT TERM HUP; do
        case $device in
            zelle) file=$dir/$device-$sig.toml; args=(zelle serve --state "$file") ;;
            cpu196) file=$dir/$device-$sig.toml; args=(cpu196 serve --image "$file") ;;
        esac
        link=$dir/$device-$sig.tty
        # stdin stays open (a FIFO held by this shell) so the server does not see its end.
        mkfifo "$dir/in-$device-$sig"
        exec 3<>"$dir/in-$device-$sig"
        "$BUSLAB" -q "${args[@]}" --link "$link" <&3 >/dev/null 2>"$dir/err" &
        pid=$!
        while [ ! -L "$link" ]; do sleep 0.05; done
        kill -s "$sig" "$pid"
        status=0
        wait "$pid" || status=$?
        exec 3>&-
        journals=$(find "$dir" -name "$device-$sig*journal*" | wc -l)
        [ -L "$link" ] && left=yes || left=no
        [ -s "$file" ] && saved=yes || saved=no
        echo "$device serve, SIG$sig: exit $status, state saved: $saved, journals left: $journals, link left: $left"
    done
done
