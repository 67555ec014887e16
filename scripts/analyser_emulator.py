"""An emulated dynamic signal analyser on this computer, to try `laminid acquire` without one.

    python scripts/analyser_emulator.py                 # an HP/Agilent/Keysight 35670A
    python scripts/analyser_emulator.py --model sr785   # a Stanford Research SR785
    python scripts/analyser_emulator.py --noise 0.2 --overload 2   # a poor set-up

`--noise` and `--overload` show what `laminid acquire` says of a point measured badly (poor
coherence; the hammer or the response input over range), before a real test shows it.

It prints the VISA address to give `laminid acquire --analyser` and serves until Ctrl-C. The
emulator is the one the tests use (tests/instrument/emulator.py): a TCP server on 127.0.0.1
that understands the commands laminid's drivers send, "hits" a simulated free plate a fixed
time after each start (no hammer needed) and serves its averaged FRF and coherence in the
analyser's own binary format. Its plate has the modes ``PLATE_MODES`` of that module: what
`laminid fit-frf` of the acquired file should find. Not an analyser: a way to see the
acquisition, the file it writes and the next steps work, before the lab's own is connected.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main(argv=None) -> int:
    from tests.instrument.emulator import (PLATE_MODES, HP35670AEmulator, PlateSimulator,
                                           SR785Emulator)

    models = {"35670a": HP35670AEmulator, "sr785": SR785Emulator}
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", choices=sorted(models), default="35670a",
                   help="the analyser to emulate (default: 35670a)")
    p.add_argument("--hit-interval", type=float, default=0.3, metavar="S",
                   help="seconds between the simulated hammer hits (default 0.3)")
    p.add_argument("--noise", type=float, default=2e-3, metavar="FRACTION",
                   help="the response's noise per hit, a fraction of the FRF's peak (default "
                        "0.002; with 5 hits, 0.2 takes the coherence at the weakest resonance "
                        "to ~0.8, below acquire's --coherence-min 0.9)")
    p.add_argument("--overload", action="append", default=[], metavar="POINT[:CHANNEL]",
                   help="make an input go over range during the POINT-th measurement since "
                        "the emulator started (1 = the first: point POINT of the first "
                        "acquire; a later acquire measures cleanly: restart the emulator to "
                        "see it again): channel 1 the hammer (the default), 2 the response; "
                        "repeat for more, e.g. --overload 2 --overload 3:2")
    a = p.parse_args(argv)
    if not a.noise >= 0:
        p.error(f"--noise {a.noise:g}: must be 0 or more (a fraction of the FRF's peak)")
    if not a.hit_interval > 0:
        p.error(f"--hit-interval {a.hit_interval:g}: must be above 0 s")
    overloads: dict = {}
    for text in a.overload:
        point, _, channel = text.partition(":")
        try:
            point, channel = int(point), int(channel or 1)
        except ValueError:
            p.error(f"--overload {text!r}: give POINT or POINT:CHANNEL, e.g. 2 or 3:2")
        if point < 1 or channel not in (1, 2):
            p.error(f"--overload {text!r}: the point is 1 or more, the channel 1 (hammer) "
                    "or 2 (response)")
        overloads[point] = tuple(sorted({*overloads.get(point, ()), channel}))
    # Ctrl-C even where the shell started it in the background (SIGINT ignored), and kill
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    emulator = models[a.model](plate=PlateSimulator(noise=a.noise),
                               hit_interval_s=a.hit_interval, overloads=overloads).start()
    modes = ", ".join(f"{f:g} Hz" for f, _ in PLATE_MODES)
    print(f"emulated {a.model.upper()} at {emulator.resource} (its plate's modes: {modes})\n"
          f"try:  laminid acquire --analyser {emulator.resource} --points 3 --no-prompt "
          f"-o try.frf.h5\n"
          f"then: laminid fit-frf try.frf.h5\n"
          + "".join(f"point {k}: {' and '.join(('hammer', 'response')[c - 1] for c in v)} "
                    "input over range\n" for k, v in sorted(overloads.items()))
          + ("(the emulator's measurements since it started: the points of the first acquire "
             "only; restart the emulator to see them again)\n" if overloads else "")
          + "Ctrl-C stops the emulator.", flush=True)
    try:
        while True:
            time.sleep(1)
    except KeyboardInterrupt:
        pass
    finally:
        emulator.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
