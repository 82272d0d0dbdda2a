"""The ``ugv`` translator (AS6091 unmanned ground vehicle services). No I/O.

JAUS -> DDS:

* ReportOdometry -> ``Odometry`` (metres, per odometer);
* ReportPlatformSpecifications -> ``PlatformSpecifications``;
* ReportPowerPlantStatus -> one ``PowerPlantStatus`` per engine/battery/fuel cell;
* ReportParkingBrake, ReportIlluminationState, ReportTransmissionState,
  ReportTransferCaseState, ReportAnnunciatorState, ReportAckermannConfiguration,
  ReportSkidSteerEffort, ReportStabilizerPosition/Effort, ReportPowerPlantConfiguration ->
  ``DeviceStatus`` (device ``parking_brake``, ``illumination``, ``transmission``,
  ``transfer_case``, ``annunciator``, ``steering``/``throttle``/``brake``,
  ``left_track``/``right_track``, ``stabilizer_<id>``, ``power_plant_<id>``).

* ReportIlluminationConfiguration, ReportAnnunciatorConfiguration,
  ReportTransmissionCapabilities, ReportStabilizerCapabilities,
  ReportPowerPlantCapabilities -> ``DeviceCapabilities`` (what lights, sounders, gears and
  transfer case modes are fitted; a stabilizer's angles and outline; a power plant's
  capacities);
* ReportPowerPlantStatus of a battery -> ``HealthStatus`` battery charge and voltage.

DDS -> JAUS (behind control, throttled): ``SkidSteerCommand`` -> SetSkidSteerEffort and
``AckermannCommand`` -> SetAckermannConfiguration (motion commands: the dead-man stop zeroes
the efforts, the Ackermann one brakes fully); ``DeviceCommand`` by device -> SetParkingBrake,
SetIlluminationState, SetTransmissionState, SetTransferCaseState, SetAnnunciatorState,
ResetOdometry, SetStabilizerPosition (``stabilizer_<id>``), SetStabilizerEffort
(``stabilizer_<id>_effort``), SetPowerPlantConfiguration (``power_plant_<id>``).

The UGV messages this translator leaves alone are listed in
:data:`NOT_TRANSLATED` (``edge-vis mappings`` prints them).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    NAN,
    Build,
    Computed,
    Const,
    From,
    Put,
    ReportRule,
    RuleTranslator,
    clamp,
    code_of,
    flags,
    get_path,
    label,
)
from edge_vis.kit import CommandRule as Cmd

UGV = "urn:jaus:jss:ugv:"

GEARS = {0: "DEFAULT", 1: "PARK", 2: "NEUTRAL", 3: "REVERSE", 4: "DRIVE", 5: "OVERDRIVE",
         6: "L1", 7: "L2", 8: "L3", 9: "L4", 10: "L5", 11: "L6"}
TRANSFER_CASE = {0: "DEFAULT", 1: "FWD", 2: "AUTO_4WD", 3: "MANUAL_LOW_4WD",
                 4: "MANUAL_HIGH_4WD", 5: "LOW_AWD", 6: "HIGH_AWD"}
POWER_STATES = {1: "POWER_ON", 2: "POWER_OFF", 3: "POWER_STANDBY"}
ODOMETERS = {1: "PLATFORM", 2: "TRIP_A", 3: "TRIP_B", 4: "TRIP_C"}
#: lights of SetIlluminationState; variable lights take a level 0..15 ("variable_light1=7")
LIGHTS = ("headlights", "left_turn_signal", "right_turn_signal", "running_lights",
          "brake_lights", "backup_lights", "visible_light_source", "ir_light_source",
          "variable_light1", "variable_light2", "variable_light3", "variable_light4",
          "high_beams", "parking_lights", "fog_lights", "hazard_lights")
#: sounders of SetAnnunciatorState, each with a level 0..15 ("horn=15")
SOUNDERS = ("horn", "siren", "backup", "variable1", "variable2")


def bits_from(names: tuple[str, ...], full: int) -> Any:
    """Converter: ``"headlights, variable_light1=7"`` -> a bit-field dict; a bare name of a
    multi-bit member means its full level ``full``; unknown names are a ValueError."""

    def convert(text: Any) -> dict[str, int]:
        out = dict.fromkeys(names, 0)
        for part in str(text or "").replace(";", ",").split(","):
            part = part.strip().lower()
            if not part:
                continue
            name, _, level = part.partition("=")
            name = name.strip()
            if name not in out:
                raise ValueError(f"unknown {name!r} (known: {', '.join(names)})")
            out[name] = int(level) if level else (1 if name in _ONE_BIT else full)
        return out

    return convert


_ONE_BIT = frozenset(LIGHTS) - {"variable_light1", "variable_light2", "variable_light3",
                                "variable_light4"}


def _brake_state(f: Mapping[str, Any]) -> str:
    actual = f.get("actual_parking_brake")
    return "" if actual is None else ("SET" if float(actual) > 0 else "RELEASED")


def _plant(*names: str) -> Computed:
    """The first of ``names`` present in the plant's status variant (NaN if none)."""

    def pick(plant: Mapping[str, Any]) -> float:
        status = plant.get("power_plant_status_var") or {}
        values = next(iter(status.values()), {}) if status else {}
        if isinstance(values, list):  # the JSIDL wraps each status record in a list
            values = values[0] if values else {}
        for name in names:
            if name in values:
                return float(values[name])
        return NAN

    return Computed(pick, " | ".join(f"power_plant_status_var.*[0].{n}" for n in names))


def _plant_kind(plant: Mapping[str, Any]) -> str:
    status = plant.get("power_plant_status_var") or {}
    return next(iter(status), "").removesuffix("_status")


def _steering(f: Mapping[str, Any]) -> str:
    return next(iter(f.get("platform_specifics") or {}), "")


def _device_pattern(prefix: str, suffix: str) -> Any:
    """Selector: device names ``<prefix><number><suffix>`` (``stabilizer_2``)."""
    pattern = re.compile(re.escape(prefix) + r"\d{1,3}" + re.escape(suffix) + "$")

    def matches(value: Any) -> bool:
        return isinstance(value, str) and bool(pattern.match(value.strip().lower()))

    matches.__doc__ = f"{prefix}<id>{suffix}"
    return matches


def _numbered(device: str) -> int:
    number = int(re.findall(r"\d+", device)[0])
    if number > 255:
        raise ValueError(f"{device}: an id is 0..255")
    return number


def _number(value: Any) -> float:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        raise ValueError("value is not set")
    return float(value)


def _plant_configuration(sample: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One plant's power state; the battery alternative carries just that state."""
    state = code_of(POWER_STATES)(sample.get("state", ""))
    return [{"power_plant_id": {"power_plant_id": _numbered(sample["device"])},
             "power_plant_configuration_var": {"battery_configuration_rec": {
                 "power_state": state}}}]


def _device(message: str, device: str, fields: Mapping[str, Any], query: str,
            service: str) -> ReportRule:
    return ReportRule(message, "DeviceStatus", {"device": Const(device), **fields},
                      query=query, service=UGV + service, rate=1.0, on_change=True)


NOT_TRANSLATED: tuple[tuple[str, str], ...] = ()


def _fitted(path: str) -> Computed:
    """The names of the set bits of bit field ``path`` (reserved ones left out)."""

    def names(f: Mapping[str, Any]) -> list[str]:
        bits = get_path(f, path) or {}
        return [n for n, v in bits.items() if v and not n.startswith("reserved")]

    return Computed(names, f"{path}: the set bits")


def _limits(*items: tuple[str, str, str]) -> Computed:
    """``limits`` from fields: (JAUS path, name, unit) each, where reported."""

    def pick(f: Mapping[str, Any]) -> list[dict[str, Any]]:
        out = []
        for path, name, unit in items:
            value = get_path(f, path)
            if value is not None:
                out.append({"name": name, "text": unit, "number": float(value)})
        return out

    return Computed(pick, ", ".join(p for p, _n, _u in items))


#: capacities of a power plant, by status alternative, with units (only where reported)
_PLANT_UNITS = {"fuel_capacity": "l", "oil_capacity": "l", "max_oil_pressure": "bar",
                "max_oil_temp": "degC", "max_engine_temp": "degC", "max_coolant_level": "l",
                "max_coolant_temp": "degC", "max_glow_plug_temp": "degC",
                "glow_plug_time": "s", "nominal_voltage": "V", "max_charge": "C",
                "max_cranking_amps": "A", "fluid_capacity": "l", "max_pressure": "bar",
                "max_temp": "degC"}


def _plant_limits(plant: Mapping[str, Any]) -> list[dict[str, Any]]:
    var = plant.get("power_plant_capabilities_var") or {}
    values = next(iter(var.values()), {}) if var else {}
    if isinstance(values, list):  # batteries: one record per cell string
        values = values[0] if values else {}
    return [{"name": n, "text": _PLANT_UNITS.get(n, ""), "number": float(v)}
            for n, v in values.items()]


def _outline(f: Mapping[str, Any]) -> list[dict[str, float]]:
    return [{"x": float(p.get("point_x", 0.0)), "y": float(p.get("point_y", 0.0)),
             "z": float(p.get("point_z", 0.0))} for p in f.get("stabilizer_dimensions_list")
            or []]


def _battery(member: str) -> Computed:
    """A battery plant's charge or voltage for HealthStatus (NaN for other plants)."""
    source = _plant(member)

    def pick(plant: Mapping[str, Any]) -> float:
        return source.fn(plant) if _plant_kind(plant) == "battery" else NAN

    return Computed(pick, f"battery_status.{member}")


def _actual_position(element: Mapping[str, Any]) -> float:
    """A stabilizer's position: SAE reports ``actual_position`` (and the commanded one),
    the IOP reading one ``position``."""
    value = element.get("actual_position", element.get("position"))
    return NAN if value is None else float(value)


class UgvTranslator(RuleTranslator):
    """UGV service set <-> odometry, platform, power plant and device topics."""

    name = "ugv"
    report_rules = (
        ReportRule("ReportOdometry", "Odometry",
                   {"odometer": From("odom", convert=label(ODOMETERS)),
                    "distance": From("odometry", convert=float, note="m")},
                   query="QueryOdometry", service=UGV + "OdometryService",
                   query_fields={"odom": 1}, rate=1.0),
        ReportRule("ReportPlatformSpecifications", "PlatformSpecifications", {
            "platform_name": From("platform_spec.mobility_platform_name", default=""),
            "steering": Computed(_steering, "platform_specifics alternative"),
            "max_forward_speed": From("platform_inertial.maximum_forward_speed", note="m/s"),
            "max_reverse_speed": From("platform_inertial.maximum_reverse_speed", note="m/s"),
            "max_rotational_speed": From("platform_inertial.maximum_rotational_speed",
                                         note="rad/s"),
            "max_forward_acceleration": From("platform_inertial.maximum_forward_acceleration",
                                             note="m/s^2"),
            "max_forward_deceleration": From("platform_inertial.maximum_forward_deceleration",
                                             note="m/s^2"),
            "front": From("platform_spec.front", note="m"),
            "back": From("platform_spec.back", note="m"),
            "left": From("platform_spec.left", note="m"),
            "right": From("platform_spec.right", note="m"),
            "top": From("platform_spec.top", note="m"),
            "bottom": From("platform_spec.bottom", note="m"),
            "wheel_base": From("platform_spec.wheel_base", note="m"),
            "track_width": Computed(
                lambda f: float(next(
                    (v[k] for v in (f.get("platform_specifics") or {}).values()
                     for k in ("track_separation", "wheel_separation") if k in v), NAN)),
                "platform_specifics.*.track_separation | wheel_separation"),
            "min_turn_radius": From("platform_specifics.ackermann.min_turn_radius", note="m"),
            "weight": From("platform_spec.vehicle_weight", note="kg"),
        }, query="QueryPlatformSpecifications", service=UGV + "PlatformSpecifications",
            rate=0.1, on_change=True),
        ReportRule("ReportPowerPlantStatus", "HealthStatus", {
            "battery_percent": _battery("percent_charge_remaining"),
            "supply_voltage": _battery("voltage"),
        }, query="QueryPowerPlantStatus", service=UGV + "PowerPlantManager",
            query_fields={"id_list": []}, rate=0.5, split="power_plant_status_list",
            require="power_plant_status_var.battery_status", merge=True,
            doc="a battery's charge and voltage; merged with the health monitor's level"),
        ReportRule("ReportIlluminationConfiguration", "DeviceCapabilities",
                   {"device": Const("illumination"), "supported": _fitted("types")},
                   query="QueryIlluminationConfiguration", service=UGV + "IlluminationService",
                   rate=0.1, on_change=True, doc="the lights fitted"),
        ReportRule("ReportAnnunciatorConfiguration", "DeviceCapabilities",
                   {"device": Const("annunciator"), "supported": _fitted("types")},
                   query="QueryAnnunciatorConfiguration", service=UGV + "AnnunciatorService",
                   rate=0.1, on_change=True, doc="the sounders fitted"),
        *(ReportRule("ReportTransmissionCapabilities", "DeviceCapabilities",
                     {"device": Const(device), "supported": _fitted(field)},
                     query="QueryTransmissionCapabilities", service=UGV + "DriveTrainDriver",
                     rate=0.1, on_change=True, doc=f"the {device.replace('_', ' ')} modes")
          for device, field in (("transmission", "transmission_bf"),
                                ("transfer_case", "transfer_case_bf"))),
        ReportRule("ReportStabilizerCapabilities", "DeviceCapabilities", {
            "device": Computed(lambda e: "stabilizer_" + str(get_path(
                e, "stabilizer_capabilities_rec.stabilizer_id", 0)), "stabilizer_<id>"),
            "limits": _limits(("stabilizer_capabilities_rec.maximum_up_angle",
                               "maximum_up_angle", "rad"),
                              ("stabilizer_capabilities_rec.maximum_down_angle",
                               "maximum_down_angle", "rad")),
            "points": Computed(_outline, "stabilizer_dimensions_list[] point_x/y/z")},
            query="QueryStabilizerCapabilities", service=UGV + "StabilizerDriver", rate=0.1,
            on_change=True, split="stabilizer_capabilities",
            doc="one sample per stabilizer: its angles (rad) and outline (m)"),
        ReportRule("ReportPowerPlantCapabilities", "DeviceCapabilities", {
            "device": Computed(lambda e: "power_plant_" + str(get_path(
                e, "power_plant_desc_rec.power_plant_id", 0)), "power_plant_<id>"),
            "supported": Computed(lambda e: [next(iter(e.get(
                "power_plant_capabilities_var") or {}), "").removesuffix("_rec")
                .removesuffix("_list").removesuffix("_capabilities")],
                "power_plant_capabilities_var alternative (gas_engine, battery ...)"),
            "limits": Computed(_plant_limits, "power_plant_capabilities_var.*: capacities")},
            query="QueryPowerPlantCapabilities", service=UGV + "PowerPlantManager",
            query_fields={"id_list": []}, rate=0.1, on_change=True,
            split="power_plant_capabilities_list",
            doc="one sample per power plant: its kind and capacities"),
        ReportRule("ReportPowerPlantStatus", "PowerPlantStatus", {
            "plant_id": From("power_plant_desc_rec.power_plant_id"),
            "description": From("power_plant_desc_rec.description", default=""),
            "kind": Computed(_plant_kind, "power_plant_status_var alternative"),
            "remaining_percent": _plant("percent_charge_remaining", "percent_remaining_fuel"),
            "voltage": _plant("voltage"),
            "current": _plant("current_draw"),
            "temperature": _plant("battery_temp", "engine_temp", "fluid_temp"),
            "hours": _plant("battery_hours", "engine_hours", "total_hours"),
        }, query="QueryPowerPlantStatus", service=UGV + "PowerPlantManager",
            query_fields={"id_list": []}, rate=0.5, split="power_plant_status_list",
            doc="one sample per power plant; an empty id list asks for all"),
        *(ReportRule("ReportAckermannConfiguration", "DeviceStatus",
                     {"device": Const(device), "value": From(field, note=unit)},
                     query="QueryAckermannConfiguration", service=UGV + "AckermannDriver",
                     rate=2.0)
          for device, field, unit in (("steering", "steering_angle", "rad"),
                                      ("throttle", "throttle_effort", "percent"),
                                      ("brake", "brake_effort", "percent"))),
        *(ReportRule("ReportSkidSteerEffort", "DeviceStatus",
                     {"device": Const(f"{side}_track"),
                      "value": From(f"{side}_side_propulsive_effort", note="percent")},
                     query="QuerySkidSteerEffort", service=UGV + "SkidSteerDriver", rate=2.0)
          for side in ("left", "right")),
        ReportRule("ReportStabilizerPosition", "DeviceStatus",
                   {"device": Computed(lambda e: f"stabilizer_{e.get('stabilizer_id', 0)}",
                                       "stabilizer_<stabilizer_id>"),
                    "value": Computed(_actual_position,
                                      "actual_position (IOP: position), rad"),
                    "commanded_value": From("commanded_position", note="rad; IOP: NaN")},
                   query="QueryStabilizerPosition", service=UGV + "StabilizerDriver",
                   query_fields={"stabilizer_id": []}, rate=1.0, split="stabilizer_position",
                   doc="one sample per stabilizer (flipper); an empty id list asks for all"),
        ReportRule("ReportStabilizerEffort", "DeviceStatus",
                   {"device": Computed(
                       lambda e: f"stabilizer_{e.get('stabilizer_id', 0)}_effort",
                       "stabilizer_<stabilizer_id>_effort"),
                    "value": From("effort", note="percent")},
                   query="QueryStabilizerEffort", service=UGV + "StabilizerDriver",
                   query_fields={"stabilizer_id": []}, rate=1.0, split="stabilizer_effort",
                   doc="one sample per stabilizer"),
        ReportRule("ReportPowerPlantConfiguration", "DeviceStatus",
                   {"device": Computed(lambda e: "power_plant_" + str(
                       get_path(e, "power_plant_id.power_plant_id", 0)),
                                       "power_plant_<power_plant_id>"),
                    "state": From("power_plant_configuration_var.*.power_state",
                                  convert=label(POWER_STATES), default="")},
                   query="QueryPowerPlantConfiguration", service=UGV + "PowerPlantManager",
                   query_fields={"id_list": []}, rate=0.5, on_change=True,
                   split="power_plant_configuration_list",
                   doc="one sample per power plant: POWER_ON, POWER_OFF, POWER_STANDBY"),
        _device("ReportParkingBrake", "parking_brake",
                {"state": Computed(_brake_state, "actual_parking_brake > 0"),
                 "value": From("actual_parking_brake", note="percent"),
                 "commanded_value": From("commanded_parking_brake", note="percent")},
                "QueryParkingBrake", "ParkingBrakeDriver"),
        _device("ReportIlluminationState", "illumination",
                {"state": From("illumination", convert=flags, default="",
                               note="lights on, comma separated")},
                "QueryIlluminationState", "IlluminationService"),
        _device("ReportTransmissionState", "transmission",
                {"state": From("actual_transmission_state", convert=label(GEARS), default=""),
                 "commanded_state": From("requested_transmission_state",
                                         convert=label(GEARS), default="")},
                "QueryTransmissionState", "DriveTrainDriver"),
        _device("ReportTransferCaseState", "transfer_case",
                {"state": From("transfer_case_state", convert=label(TRANSFER_CASE),
                               default="")},
                "QueryTransferCaseState", "DriveTrainDriver"),
        _device("ReportAnnunciatorState", "annunciator",
                {"state": From("annunciator", default="",
                               convert=lambda b: flags({k: v for k, v in b.items()
                                                        if k != "reserved"}),
                               note="sounders on, comma separated")},
                "QueryAnnunciatorState", "AnnunciatorService"),
    )
    command_rules = (
        Cmd("SkidSteerCommand", "SetSkidSteerEffort", UGV + "SkidSteerDriver", "skid_steer",
            {"left_side_propulsive_effort": Put("left_effort", -100.0, 100.0, note="percent"),
             "right_side_propulsive_effort": Put("right_effort", -100.0, 100.0,
                                                 note="percent")},
            stop={"left_side_propulsive_effort": 0.0, "right_side_propulsive_effort": 0.0},
            doc="motion: dead-man stop zeroes both tracks"),
        Cmd("AckermannCommand", "SetAckermannConfiguration", UGV + "AckermannDriver",
            "ackermann",
            {"steering_angle": Put("steering_angle", -math.pi / 2, math.pi / 2, note="rad"),
             "throttle_effort": Put("throttle_effort", 0.0, 100.0, note="percent"),
             "brake_effort": Put("brake_effort", 0.0, 100.0, note="percent"),
             "max_steering_rate": Put("max_steering_rate", 0.0, 32.767, optional=True,
                                      note="rad/s"),
             "max_steering_torque": Put("max_steering_torque", 0.0, 500.0, optional=True,
                                        note="N m")},
            stop=lambda f: {"steering_angle": f["steering_angle"], "throttle_effort": 0.0,
                            "brake_effort": 100.0},
            doc="motion: dead-man stop closes the throttle and brakes fully"),
        Cmd("DeviceCommand", "SetParkingBrake", UGV + "ParkingBrakeDriver", "parking_brake",
            {"parking_brake": Put("value", 0.0, 100.0, note="percent")},
            when={"device": "parking_brake"}),
        Cmd("DeviceCommand", "SetIlluminationState", UGV + "IlluminationService",
            "illumination",
            {"illumination": Put("state", convert=bits_from(LIGHTS, 15), default="",
                                 note="comma-separated lights to switch on")},
            when={"device": "illumination"}),
        Cmd("DeviceCommand", "SetTransmissionState", UGV + "DriveTrainDriver", "transmission",
            {"transmission_state": Put("state", convert=code_of(GEARS), note="gear name")},
            when={"device": "transmission"}),
        Cmd("DeviceCommand", "SetTransferCaseState", UGV + "DriveTrainDriver", "transfer_case",
            {"transfer_case_state": Put("state", convert=code_of(TRANSFER_CASE))},
            when={"device": "transfer_case"}),
        Cmd("DeviceCommand", "SetAnnunciatorState", UGV + "AnnunciatorService", "annunciator",
            {"annunciator": Put("state", convert=bits_from(SOUNDERS, 15), default="",
                                note="comma-separated sounders, optional =level")},
            when={"device": "annunciator"}),
        Cmd("DeviceCommand", "SetStabilizerPosition", UGV + "StabilizerDriver", "stabilizer",
            {"stabilizer_position": Build("device, value", lambda s: [{
                "stabilizer_id": _numbered(s["device"]),
                "position": clamp(_number(s.get("value")), -math.pi, math.pi)}],
                "stabilizer_<id> -> stabilizer_id; value rad, clamped to +-pi")},
            when={"device": _device_pattern("stabilizer_", "")}),
        Cmd("DeviceCommand", "SetStabilizerEffort", UGV + "StabilizerDriver",
            "stabilizer_effort",
            {"stabilizer_effort": Build("device, value", lambda s: [{
                "stabilizer_id": _numbered(s["device"]),
                "effort": clamp(_number(s.get("value")), -100.0, 100.0)}],
                "stabilizer_<id>_effort -> stabilizer_id; value percent, clamped")},
            when={"device": _device_pattern("stabilizer_", "_effort")},
            stop=lambda f: {"stabilizer_effort": [{**e, "effort": 0.0}
                                                  for e in f["stabilizer_effort"]]},
            doc="motion: dead-man stop"),
        Cmd("DeviceCommand", "SetPowerPlantConfiguration", UGV + "PowerPlantManager",
            "power_plant",
            {"power_plant_configuration_list": Build("device, state", _plant_configuration,
                                                     "power_plant_<id>; state POWER_ON, "
                                                     "POWER_OFF or POWER_STANDBY")},
            when={"device": _device_pattern("power_plant_", "")}),
        Cmd("DeviceCommand", "ResetOdometry", UGV + "OdometryService", "odometry",
            {"odometry_type": Put("state", convert=code_of(
                {k: v for k, v in ODOMETERS.items() if k != 1}), note="TRIP_A|B|C")},
            when={"device": "odometer"}),
    )
    not_translated = NOT_TRANSLATED
