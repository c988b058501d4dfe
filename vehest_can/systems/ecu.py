"""The ECU firmware (``vh_ecu_t``) seen from Python: frames in, a tick, frames out.

It holds every system's app, so it sits with the systems and takes their configurations; the
sessions below it (``sim.session.run_inprocess``) are handed an ECU rather than making one."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import can

from ..bus.frames import to_frame, to_message
from ..errors import ConfigError
from ..native import check, ffi, lib

COUNTERS = (
    "crc_error", "counter_repeat", "counter_skip", "dlc_error", "timeout", "unknown_id",
    "signal_invalid", "input_invalid", "filter_reset", "deadline_miss", "rx_burst", "secoc_reject",
)
HEALTH = {0: "INIT", 1: "OK", 2: "DEGRADED", 3: "FAULT"}
class CounterSet:
    """A C counter set read by name. The C counts in uint32 and saturates at 2^32 - 1 (never wraps:
    vh_sat_add_u32), so what it holds is the total since reset; only the status frames' 16-bit fields
    stop at 65535 (their CntSaturated bit then set)."""

    def __init__(self, read, names: tuple[str, ...]):
        self._read = read  # () -> the C struct holding `names`
        self.names = names

    def poll(self) -> dict[str, int]:
        c = self._read()
        return {name: int(getattr(c, name)) for name in self.names}


def _systems():
    from . import registered

    return registered()


@dataclass
class EcuConfig:
    #: more good frames of one message in a tick than this is a burst (stale samples of a draining
    #: queue), not used until the message is regular again; 0 switches the check off
    rx_burst_frames: int = 2
    #: each system's part by its name, as its ``configure_ecu`` takes it; absent: its default
    systems: dict[str, Any] = field(default_factory=dict)
    #: the car every system's model is calibrated for (a :class:`~vehest_can.carfile.CarFile`); None: the
    #: paper's (firmware_sim/cars/paper.toml, the C defaults bit for bit). A system's part overrides it.
    car: Any = None

    @classmethod
    def default(cls) -> EcuConfig:
        return cls()

    def to_c(self):
        c = ffi.new("vh_ecu_config_t *")
        lib.vh_ecu_config_default(c)
        if not 0 <= self.rx_burst_frames <= 255:
            raise ConfigError(f"rx_burst_frames must be 0..255 (0 = off), got {self.rx_burst_frames}")
        c.rx_burst_frames = self.rx_burst_frames
        if self.car is not None:  # the paper's car is the C default byte for byte (tests/test_carfile.py)
            write_car(c.app, self.car)
        for s in _systems():
            if hasattr(s, "configure_ecu"):  # optional: without it, the C core's default
                s.configure_ecu(c.app, self.systems.get(s.name))
        return c


def write_car(app, car=None) -> None:
    """A car (None: the paper's) into every system's configuration in ``app`` (``vh_ecu_apps_config_t``)."""
    from ..carfile import paper_car

    car = paper_car() if car is None else car
    for s in _systems():
        if hasattr(s, "configure_car"):
            s.configure_car(app, car)


def _ecu_refusal(car) -> str | None:
    """What in the C refuses an ECU calibrated for `car` (each application's host completion and check,
    the configuration checks of the filters), or None when it accepts it."""
    c = ffi.new("vh_ecu_config_t *")
    lib.vh_ecu_config_default(c)
    write_car(c.app, car)
    app = c.app
    if not lib.vh_skf_config_check(ffi.addressof(app.tf, "skf")):
        return "vh_skf_config_check (SKFMEC)"
    if lib.vh_skfq_params_from_config(ffi.addressof(app.tf, "skf"), ffi.new("vh_skfq_params_t *")) != lib.VH_OK:
        return "vh_skfq_params_from_config (the fixed-point SKFMEC's constants)"
    if lib.vh_tfa_params_from_config(ffi.addressof(app.tf, "skf"), ffi.addressof(app.tf, "tfa"),
                                     ffi.new("vh_tfa_params_t *")) != lib.VH_OK:
        return "vh_tfa_params_from_config (SKFMEC-A's constants)"
    tf = ffi.new("vh_tf_app_config_t *", app.tf)
    if lib.vh_tf_app_config_host(tf) != lib.VH_OK or lib.vh_tf_app_check(tf) != lib.VH_OK:
        return "vh_tf_app_check (the tyre-force application: its integer TX fractions)"
    if lib.vh_roll_params_check(ffi.addressof(app.roll, "ukf")) != 0:
        return "vh_roll_params_check (the roll UKF)"
    if lib.vh_roll_smc_params_check(ffi.addressof(app.roll, "smc")) != 0:
        return "vh_roll_smc_params_check (the roll SMC)"
    if lib.vh_ecu_init(ffi.new("vh_ecu_t *"), c) != lib.VH_OK:
        return "vh_ecu_init"
    return None


def _plant_refusal(car) -> str | None:
    if lib.vh_v14_init(ffi.new("vh_v14_t *"), car.veh14_params(ffi, lib)) != lib.VH_OK:
        return "vh_v14_init (the 14-DOF plant)"
    return None


def check_car(car, *, plant: bool = True) -> None:
    """The C's checks of an ECU calibrated for `car` (and, with `plant`, of the 14-DOF plant with it). A
    refusal is a ConfigError naming the key to blame: the one whose value from the paper's car makes the C
    accept the rest of this car (the Python ranges of ``load_car`` come first; this names what they miss)."""
    from ..carfile import blame

    for refusal in (_ecu_refusal, _plant_refusal) if plant else (_ecu_refusal,):
        what = refusal(car)
        if what is not None:
            raise ConfigError(blame(car, what, lambda c, r=refusal: r(c) is None))


class Ecu:
    """One ECU instance. ``rx`` every received frame, then ``step`` once per 500 µs tick."""

    def __init__(self, config: EcuConfig | None = None):
        self.config = config or EcuConfig.default()
        self._c_config = self.config.to_c()
        self.c = ffi.new("vh_ecu_t *")
        if lib.vh_ecu_init(self.c, self._c_config) != lib.VH_OK and self.config.car is not None:
            check_car(self.config.car, plant=False)  # names the car's key when it is the car
        check(lib.vh_ecu_init(self.c, self._c_config), "ECU configuration")
        self._rx = ffi.new("vh_frame_t *")
        self._tx = ffi.new("vh_frame_t[]", lib.VH_ECU_MAX_TX)
        self._own = CounterSet(lambda: self.c.cnt, COUNTERS)
        #: the counter sets the systems' applications keep (System.ecu_counters), by name
        self._sets = {s.name: CounterSet(lambda read=s.read: read(self.c), s.names)
                      for system in _systems() for s in getattr(system, "ecu_counters", ())}
        self._steps = 0
        self.secoc: Any = None  # SecOC off until enable_secoc (a vehest_can.bus.secoc.BusSecoc)

    def enable_secoc(self, keys: dict, store=None):
        """SecOC on, as node VEHEST (keys: vehest_can.bus.secoc.load_keys; store: its FreshnessStore
        or None): its secured frames are protected and every secured frame it receives is verified in
        the C before any system sees it. Returns the node's BusSecoc (its counters)."""
        from ..bus.secoc import BusSecoc

        self.secoc = BusSecoc("VEHEST", keys, store=store)
        lib.vh_ecu_set_secoc(self.c, self.secoc.c)
        return self.secoc

    def reset(self) -> None:
        """A new session (the lockstep RESET): the C's reset, and SecOC restarted as by a new process
        (vh_ecu_reset alone keeps the freshness: a firmware reset must not reuse FVs)."""
        lib.vh_ecu_reset(self.c)
        if self.secoc is not None:
            self.secoc.restart()

    def poll_counters(self) -> None:
        """Nothing to do in process: the C counters are the totals. A remote ECU (the emulated
        target) refreshes its host mirror here."""

    def rx(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        self.rx_frame(to_frame(msg, self._rx))

    def rx_frame(self, frame) -> None:
        """A ``vh_frame_t *`` straight from a C node (in-process runs)."""
        lib.vh_ecu_rx(self.c, frame)

    def step_frames(self) -> list:
        """One tick; the frames to transmit as ``vh_frame_t`` cdata (valid until the next step)."""
        n = lib.vh_ecu_step(self.c, self._tx, lib.VH_ECU_MAX_TX)
        self._steps += 1
        if self.secoc is not None and self._steps % lib.VH_SECOC_SYNC_PERIOD_TICKS == 0:
            self.secoc.maintain()  # once a second: the FV reservation ahead, the receivers' state stored
        return [self._tx[i] for i in range(n)]

    def step(self, timestamp: float = 0.0) -> list[can.Message]:
        return [to_message(f, timestamp) for f in self.step_frames()]

    def note_deadline_miss(self, n: int = 1) -> None:
        lib.vh_ecu_note_deadline_miss(self.c, min(n, 0xFFFF_FFFF))  # the C saturates the sum

    @property
    def tick(self) -> int:
        return int(self.c.tick)

    def counters(self) -> dict[str, int]:
        """The powertrain side's fault counters since reset, all 32 bits (VEHEST_Status carries each
        saturated at 65535)."""
        return self._own.poll()

    @staticmethod
    def estimators():
        """Every registered system's estimators (:class:`~vehest_can.systems.EcuEstimator`)."""
        return [e for s in _systems() for e in s.estimators]

    def heard(self) -> dict[str, bool]:
        """Whether each estimator's sensor frame has been received (a good CRC) since reset."""
        return {e.input: e.heard(self.c) for e in self.estimators()}

    def not_heard(self) -> list[str]:
        """The estimators whose sensor frame has never been heard: not configured or absent, not failed."""
        return [e.name for e in self.estimators() if not e.heard(self.c)]

    def health(self) -> dict[str, str]:
        return {e.name: HEALTH[int(e.health(self.c))] for e in self.estimators()}

    def system_counters(self, name: str) -> dict[str, int]:
        """A system's counter set (:class:`~vehest_can.systems.EcuCounters`) since reset, all 32 bits."""
        return self._sets[name].poll()

    def chassis_counters(self) -> dict[str, int]:
        """The chassis bus's own counter set (VEHEST_ChassisStatus) since reset, all 32 bits."""
        return self.system_counters("chassis")
