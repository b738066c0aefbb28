"""The stress a walker is trained and priced under: a datapack's conditions, drawn per episode.

:meth:`Stress.from_datapacks` reads the datapack schema's own keys (:mod:`econmotor.config.datapacks`)
for both walker envs, the MuJoCo C one (:mod:`.env`, through :mod:`.conditions`) and the MJX
one (:mod:`econmotor.motor_backend.mjx.humanoid_env`). ``domain_randomization`` keys:

============================  ======================================================================
datapack key                  :class:`Stress` field
============================  ======================================================================
``friction_range``            ``friction_range``: the floor's sliding friction, one draw per episode
``added_base_mass_kg``        ``payload_kg_range``: a payload on the torso, kg, one draw per episode
``pushes``                    ``true``: base velocity kicks at the card's ``push_preset`` (Holosoma's push
                              interval and velocity); ``false``: none, whatever the two keys below say
``push_interval_s``           ``push_interval_s``: the time to the next kick, s, drawn from the range
``max_push_vel_m_per_s``      ``max_push_vel_m_per_s``: a kick of up to that many m/s in x and y
``kp_range`` / ``kd_range``   ``kp_range`` / ``kd_range``: the PD gains scaled per joint by a draw, one per
                              episode (Holosoma's ``actuator_randomizer_state``)
``ctrl_delay_steps``          ``ctrl_delay_steps``: the action applied is the one from that many control
                              steps earlier, an integer draw per episode from the rounded inclusive range
``initial_joint_noise_rad``   ``initial_joint_noise_rad``: each joint starts within +- this of its default
                              angle (without it: the catalog's start-pose noise)
``terrain``                   ``flat`` / ``plane``: the walker's floor; ``rough`` / ``mixed``: not applied
============================  ======================================================================

Either push key alone turns pushes on, the other taken from the card's preset. A walker env does not
apply ``link_mass_range``, a rough ``terrain``, a ``curriculum`` or ``motion_clips`` (nor what an env
says it lacks: the MJX env has no control delay); those raise a ConfigError naming the datapack file and
key, or, for a policy priced under conditions it was trained under elsewhere (Holosoma's training applies
them), are listed in ``Stress.ignored``. Any other key is a ConfigError listing the keys above.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from econmotor.config.loading import as_float, as_range, as_str
from econmotor.errors import ConfigError

#: datapack range key -> (Stress field, the range's lowest allowed value)
_RANGES = {"friction_range": ("friction_range", 0.0), "added_base_mass_kg": ("payload_kg_range", None),
           "push_interval_s": ("push_interval_s", 0.0), "kp_range": ("kp_range", 0.0),
           "kd_range": ("kd_range", 0.0), "ctrl_delay_steps": ("ctrl_delay_steps", 0.0),
           "link_mass_range": (None, 0.0)}
TERRAINS = ("flat", "plane", "rough", "mixed")
#: the ``domain_randomization`` keys a walker reads (it applies all but ``link_mass_range`` and a rough terrain)
STRESS_KEYS = (*_RANGES, "pushes", "max_push_vel_m_per_s", "initial_joint_noise_rad", "terrain")
_FLAT = ("flat", "plane")


def _pair(value: Any) -> tuple[float, float] | None:
    return (float(value[0]), float(value[1])) if value is not None else None


def _sourced(datapacks: Sequence[Any]) -> tuple[dict[str, tuple[Any, str]], list[tuple[str, str, str]]]:
    """The datapacks' ``domain_randomization`` merged in order (later packs win), each key with the file that set
    it, and ``(file, key, why)`` for their curricula and motion clips (a walker applies neither).

    A datapack is a :class:`~econmotor.config.datapacks.DatapackConfig` (its ``source``) or a resolved
    :class:`~econmotor.config.datapacks.DatapackBundle` (its packs' ``sources``, named together)."""
    keys: dict[str, tuple[Any, str]] = {}
    unapplied: list[tuple[str, str, str]] = []
    for pack in datapacks:
        source = getattr(pack, "source", None) or ", ".join(getattr(pack, "sources", {}).values()) or "<datapacks>"
        for key, value in (getattr(pack, "domain_randomization", None) or {}).items():
            keys[key] = (value, source)
        unapplied += [(source, f"curriculum.{key}", "a walker env has no curriculum: its ranges apply as written")
                      for key in getattr(pack, "curriculum", None) or {}]
        clips = len(getattr(pack, "motion_clips", None) or ())
        if clips:
            unapplied.append((source, "motion_clips", f"{clips} clip(s): a walker tracks the course's velocity "
                                                      "commands, not clips (humanoid_wbt_g1 tracks clips)"))
    return keys, unapplied


@dataclass(frozen=True)
class Stress:
    """Datapack conditions applied per episode (None: nominal); the module docstring has each field.

    ``ignored``: ``"file: key (why)"`` of what the datapacks set and a walker env does not apply (only where
    :meth:`from_datapacks` was told not to refuse it).
    """

    friction_range: tuple[float, float] | None = None
    payload_kg_range: tuple[float, float] | None = None
    push_interval_s: tuple[float, float] | None = None
    max_push_vel_m_per_s: tuple[float, float] | None = None
    initial_joint_noise_rad: float = 0.0
    kp_range: tuple[float, float] | None = None
    kd_range: tuple[float, float] | None = None
    ctrl_delay_steps: tuple[int, int] | None = None
    ignored: tuple[str, ...] = ()

    @property
    def nominal(self) -> bool:
        """Whether episodes differ in their start pose only (nothing else is drawn)."""
        return (self.friction_range, self.payload_kg_range, self.push_interval_s, self.kp_range, self.kd_range,
                self.ctrl_delay_steps) == (None,) * 6

    @classmethod
    def from_datapacks(cls, datapacks: Sequence[Any], push_preset: Mapping[str, Any],
                       start_joint_noise_rad: float = 0.0, *, lacks: Sequence[str] = (),
                       refuse_unapplied: bool = True) -> Stress:
        """The stress of ``datapacks`` (configs or resolved bundles, merged in order: later keys win), read from
        the datapack keys of the module docstring.

        Args:
            datapacks: :class:`~econmotor.config.datapacks.DatapackConfig` or ``DatapackBundle`` values.
            push_preset: the robot card's ``push_preset`` (``push_interval_s`` range, s; ``max_push_vel``
                in x and y, m/s): what ``pushes: true`` means, and the push key a datapack leaves out.
            start_joint_noise_rad: the catalog's start-pose noise, rad, unless a datapack sets
                ``initial_joint_noise_rad``.
            lacks: ``domain_randomization`` keys the calling env cannot apply besides the module's
                (the MJX env: ``ctrl_delay_steps``).
            refuse_unapplied: True: what a walker env cannot apply is a ConfigError naming the datapack file
                and key; False: it is listed in ``Stress.ignored`` (pricing a policy trained under it elsewhere).

        Raises:
            ConfigError: naming the file and key of an unknown key, a malformed value or (with
                ``refuse_unapplied``) a key a walker env cannot apply.
        """
        keys, unapplied = _sourced(datapacks)
        fields: dict[str, Any] = {}
        pushes: bool | None = None
        for key, (value, src) in keys.items():
            dotted = f"domain_randomization.{key}"
            if key not in STRESS_KEYS:
                raise ConfigError(src, dotted, "a walker env has no such stress", STRESS_KEYS)
            if key in _RANGES:
                field_name, low = _RANGES[key]
                pair = as_range(value, src, dotted, min_value=low)
                if key == "ctrl_delay_steps":
                    pair = (round(pair[0]), round(pair[1]))
                if field_name is None:
                    unapplied.append((src, dotted, "a walker env scales no link masses"))
                else:
                    fields[field_name] = pair
            elif key == "pushes":
                if not isinstance(value, bool):
                    raise ConfigError(src, dotted, f"expected true or false, got {value!r}")
                pushes = value
            elif key == "max_push_vel_m_per_s":
                v = as_float(value, src, dotted, min_value=0.0)
                fields["max_push_vel_m_per_s"] = (v, v)
            elif key == "initial_joint_noise_rad":
                fields["initial_joint_noise_rad"] = as_float(value, src, dotted, min_value=0.0)
            elif as_str(value, src, dotted, TERRAINS) not in _FLAT:
                unapplied.append((src, dotted, f"'{value}': a walker env walks on flat ground"))
            if key in lacks:
                unapplied.append((src, dotted, "this walker env cannot apply it"))
        if pushes is not None or "push_interval_s" in fields or "max_push_vel_m_per_s" in fields:
            interval = fields.pop("push_interval_s", push_preset["push_interval_s"])
            velocity = fields.pop("max_push_vel_m_per_s", push_preset["max_push_vel"])
            if pushes is not False:
                fields["push_interval_s"], fields["max_push_vel_m_per_s"] = _pair(interval), _pair(velocity)
        if unapplied and refuse_unapplied:
            src, key, why = unapplied[0]
            raise ConfigError(src, key, f"not applied by a walker env ({why})")
        delay = fields.pop("ctrl_delay_steps", None)
        return cls(**{k: _pair(v) for k, v in fields.items() if k != "initial_joint_noise_rad"},
                   initial_joint_noise_rad=float(fields.get("initial_joint_noise_rad", start_joint_noise_rad)),
                   ctrl_delay_steps=(int(delay[0]), int(delay[1])) if delay is not None else None,
                   ignored=tuple(f"{src}: {key} ({why})" for src, key, why in unapplied))
