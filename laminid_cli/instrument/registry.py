"""Driver registry and auto-detection from ``*IDN?``.

Every module of this package that defines ``DRIVER`` (an :class:`~.base.Analyser` subclass) is
a driver; adding an analyser is one new module, nothing to register by hand.
"""

from __future__ import annotations

import importlib
import logging
import pkgutil

from laminid_cli.errors import InstrumentError
from laminid_cli.instrument.base import Analyser
from laminid_cli.instrument.transport import (DEFAULT_TIMEOUT_S, AnalyserSetupError, Transport,
                                              open_transport)

log = logging.getLogger(__name__)

_INFRASTRUCTURE = {"base", "transport", "registry", "session", "testing"}


def drivers() -> dict[str, type[Analyser]]:
    """Model name (upper case) -> driver class, for every driver module of the package."""
    import laminid_cli.instrument as pkg

    found = {}
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if info.name in _INFRASTRUCTURE or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{pkg.__name__}.{info.name}")
        driver = getattr(module, "DRIVER", None)
        if driver is not None:
            found[driver.MODEL.upper()] = driver
    return found


def model_names() -> list[str]:
    return [d.MODEL for d in drivers().values()]


def _key(name: str) -> str:
    return "".join(ch for ch in name.lower() if ch.isalnum())


def find_driver(model: str) -> type[Analyser] | None:
    """The driver whose model name or one of its ``ALIASES`` is ``model`` (case, spaces and
    dashes ignored: ``HP35670A``, ``keysight-35670a`` and ``35670A`` are the same)."""
    key = _key(model)
    for driver in drivers().values():
        if key in {_key(driver.MODEL), *(_key(a) for a in getattr(driver, "ALIASES", ()))}:
            return driver
    return None


def accepted_names() -> list[str]:
    """Every name ``--model`` accepts (besides auto)."""
    names = []
    for driver in drivers().values():
        names += [a for a in getattr(driver, "ALIASES", ()) if a not in names]
    return names


def driver_for(model: str, idn: str, resource: str = "") -> type[Analyser]:
    """The driver for ``model`` (``"auto"``: the one whose ``matches(idn)`` is true)."""
    table = drivers()
    where = f" at {resource}" if resource else ""
    if model.lower() == "auto":
        for driver in table.values():
            if driver.matches(idn):
                return driver
        if not idn.strip():
            raise AnalyserSetupError(
                f"the instrument{where} gave an empty answer to *IDN?; check the address "
                f"(supported analysers: {', '.join(model_names())})")
        raise AnalyserSetupError(
            f"the analyser{where} answers *IDN? with {idn!r}, which no laminid driver supports "
            f"(supported: {', '.join(model_names())}); use --model to force one")
    driver = find_driver(model)
    if driver is None:
        raise AnalyserSetupError(f"unknown analyser model {model!r}; choose auto or one of: "
                                 f"{', '.join(accepted_names())} (case-insensitive)")
    if not driver.matches(idn):
        # another supported analyser: forcing a driver on it timed out on the first command
        # it does not know (SR785's 'FSTR? 0' on a 35670A), naming neither model
        other = next((d for d in table.values() if d.matches(idn)), None)
        if other is not None:
            raise AnalyserSetupError(
                f"--model {model}: the analyser{where} identifies as the {other.MODEL} "
                f"({idn!r}), not the {driver.MODEL}; use --model auto or the {other.MODEL}'s "
                "name (--model forces a driver on an analyser whose *IDN? none recognises)")
        log.warning("--model %s forced, but the analyser identifies as %r", driver.MODEL, idn)
    return driver


def connect(transport: Transport, model: str = "auto", poll_s: float = 0.05) -> Analyser:
    """Identify the analyser on ``transport`` and return its driver (closes it on failure)."""
    try:
        try:
            idn = transport.query("*IDN?")
        except InstrumentError as exc:
            # nothing answers the first query (a wrong GPIB address or port, the analyser off):
            # bad input as a refused connection is (exit 2), with what to check
            raise AnalyserSetupError(
                f"{exc}: no analyser answering there; check the address (GPIB address, host "
                "and port), that the analyser is on and its GPIB or LAN interface enabled, "
                "or allow it longer (--timeout)") from exc
        driver = driver_for(model, idn, transport.resource)
    except BaseException:
        transport.close()
        raise
    log.info("analyser %s: %s (driver %s)", transport.resource, idn, driver.__name__)
    return driver(transport, idn=idn, poll_s=poll_s)


def open_analyser(resource: str, model: str = "auto", backend: str | None = None,
                  timeout: float = DEFAULT_TIMEOUT_S, poll_s: float = 0.05) -> Analyser:
    """Open a VISA resource and return the matching driver (a context manager)."""
    return connect(open_transport(resource, backend=backend, timeout=timeout), model, poll_s)
