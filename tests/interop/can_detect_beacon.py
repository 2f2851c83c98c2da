"""python-can 4.6.1's detect_beacon() finds `buslab bus serve --beacon`.

Usage: can_detect_beacon.py   (prints one line per configuration found: HOST PORT CHANNEL)

detect_beacon() returns at the first beacon (one every 3 s); the long timeout is only a
deadline for that event on a loaded machine.
"""

from can.interfaces.socketcand import detect_beacon

for config in detect_beacon(60000):
    print(config["interface"], config["host"], config["port"], config["channel"], flush=True)
