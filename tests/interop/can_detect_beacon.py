"""python-can 4.6.1's detect_beacon() finds `buslab bus serve --beacon`.

Usage: can_detect_beacon.py   (prints one line per configuration found: HOST PORT CHANNEL)
"""

from can.interfaces.socketcand import detect_beacon

for config in detect_beacon(5000):
    print(config["interface"], config["host"], config["port"], config["channel"], flush=True)
