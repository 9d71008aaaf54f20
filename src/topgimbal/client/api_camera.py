"""Typed methods, part 3: the camera (photos, recording, SD card, zoom, focus, thermal, range,
network)."""

from __future__ import annotations

import asyncio
from typing import Protocol

from ..errors import FieldValueError, RequestTimeoutError, UnsupportedError
from ..geo import Fix, GridTerrain, Uncertainty
from ..protocol import Message
from ..timeouts import within
from . import checks, roles
from .api_core import fields_of, request, send_values
from .core import ClientCore
from .methods import api_method
from .state import SdCard

# API name -> catalog role of the command that holds the setting.
NETWORK = (("ip", "ip_address"), ("gateway", "gateway"), ("dns", "dns"), ("backup_dns", "backup_dns"))


def _rec(core: ClientCore) -> str:
    return roles.require_role(core.dialect, core.model, "recording", "video recording")


class CameraMethods(Protocol):
    @api_method
    async def photo(core: ClientCore, **values: object) -> Message:
        """Take one photo. Sent once, never retried (a copy would take a second photo); when no
        acknowledgement comes, the error says the photo may or may not have been taken."""
        ident = roles.require_role(core.dialect, core.model, "photo", "photo command")
        core.behaviour.note_camera_command("photo")
        try:
            return await send_values(core, ident, values)
        except RequestTimeoutError as exc:
            # The key words first: a failure text may be cut (MAVLink's STATUSTEXT: 200 bytes).
            raise RequestTimeoutError(
                f"the photo may or may not have been taken: no acknowledgement ({exc}). "
                f"{ident} is never sent twice because every copy takes a photo. To check, compare the SD card's "
                f"free space (sd_card(), `topgimbal sd`) with before, or watch for the camera's CAP feedback "
                f"(subscribe(callback, {ident!r}))."
            ) from None

    @api_method
    async def start_recording(core: ClientCore) -> None:
        core.behaviour.note_camera_command("recording")
        await request(core, _rec(core), action="start")
        core.state.set("recording", True)

    @api_method
    async def stop_recording(core: ClientCore) -> None:
        await request(core, _rec(core), action="stop")
        core.state.set("recording", False)

    @api_method
    async def toggle_recording(core: ClientCore) -> None:
        """Sent once (a copy would toggle back)."""
        await request(core, _rec(core), action="toggle")

    @api_method
    async def recording(core: ClientCore) -> bool:
        m = await request(core, _rec(core), read=True)
        rec = fields_of(m).get("state") == "recording"
        core.state.set("recording", rec)
        return rec

    @api_method
    async def sd_card(core: ClientCore) -> SdCard:
        spec = roles.require(core.dialect, core.model, "sd_capacity", "SD card query")
        queries = [core.build_from(spec.ident, q, read=True) for q in roles.sd_card_queries(spec)]
        answers = [fields_of(await core.send_request(q)) for q in queries]
        sd = SdCard(*roles.sd_card_figures(answers))
        core.state.set("sd", sd)
        return sd

    @api_method
    async def zoom(core: ClientCore, action_or_level: str | float) -> None:
        """`"in"`, `"out"`, `"stop"` (continuous optical zoom), or a magnification: optical where the
        model has a magnification command, digital otherwise."""
        if isinstance(action_or_level, str) and not roles.is_number_text(action_or_level):
            zmc = roles.require(core.dialect, core.model, "zoom_control", "continuous zoom")
            await request(core, zmc.ident, action=roles.ZOOM_ALIASES.get(action_or_level, action_or_level))
            return
        level = float(action_or_level)
        optical = roles.role_ident(core.dialect, core.model, "optical_zoom")
        if optical is not None:
            await request(core, optical, magnification_x=level)
        else:
            await digital_zoom(core, level)
        core.state.set("zoom", level)

    @api_method
    async def digital_zoom(core: ClientCore, level_or_action: str | float, *, lens: str = "visible") -> None:
        """A digital zoom level or `"in"` / `"out"` steps."""
        ident = roles.require_role(core.dialect, core.model, "digital_zoom", "digital zoom")
        values = roles.digital_zoom_values(core.spec(ident), core.model, level_or_action, lens)
        await send_values(core, ident, values)

    @api_method
    async def focus(core: ClientCore, action: str) -> None:
        """One of `roles.focus_actions()`: plus, minus, stop, auto, manual, manual_save, auto_save."""
        spec = roles.require(core.dialect, core.model, "focus_control", "focus control")
        allowed = roles.focus_actions(core.dialect)
        full = roles.FOCUS_ALIASES.get(action, action)
        if full not in roles.enum_names(spec, "action"):
            raise FieldValueError("action", action, "one of " + ", ".join(allowed))
        await request(core, spec.ident, action=full)

    @api_method
    async def palette(core: ClientCore, name: str | None = None) -> str:
        """Read (no argument) or set the thermal palette."""
        ident = roles.require_role(core.dialect, core.model, "palette", "thermal palette")
        if name is None:
            return str(fields_of(await request(core, ident, read=True))["palette"])
        await request(core, ident, palette=name)
        return name

    @api_method
    async def thermal(core: ClientCore, setting: str, value: object = None) -> object:
        """Read or set one thermal setting by catalog name or identifier: `palette`, `scene`,
        `shutter`, `detail`, `brightness`, `contrast`, `spatial_denoise`, `temporal_denoise`,
        `gamma`, `range`."""
        ident = roles.thermal_ident(core.dialect, core.model, setting)
        spec = core.spec(ident)
        writing = value is not None
        form = spec.forms_for("w" if writing else "r", "request" if writing else "response")
        if not form or not form[0].fields:
            raise UnsupportedError(f"{ident} cannot be {'set' if writing else 'read'} on the {core.model.name}")
        name = form[0].fields[-1].name
        if not writing:
            return fields_of(await request(core, ident, read=True))[name]
        await send_values(core, ident, {name: value})
        return value

    @api_method
    async def locate(
        core: ClientCore,
        *,
        terrain: GridTerrain | str | None = None,  # a loaded model or a GeoTIFF path
        laser: bool = False,
        ground_alt_m: float | None = None,
        position: tuple[float, float, float] | None = None,
        heading_deg: float | None = None,
        uncertainty: Uncertainty | None = None,
    ) -> Fix | None:
        """Where the camera looks now: a `topgimbal.geo.Fix` (lat/lon/alt, slant range, `source`
        "laser+terrain", "laser", "terrain" or "flat", and a 1-sigma horizontal `error_m`), or None
        when nothing is known to be hit (sky; off the terrain model; no flat ground given).
        The vehicle's position and heading are the last fed (`feed()`), or `position=(lat, lon,
        alt MSL)` and `heading_deg`; `terrain` a GeoTIFF DEM path (or a loaded GridTerrain);
        `laser=True` measures the range first (sending `position` to the camera beforehand);
        `ground_alt_m` the flat ground's altitude used when nothing better hits."""
        from .locating import locate_now

        fix, _ = await locate_now(
            core,
            terrain=terrain,
            laser=laser,
            ground_alt_m=ground_alt_m,
            position=position,
            heading_deg=heading_deg,
            uncertainty=uncertainty or Uncertainty(),
            measure_range=lambda: CameraMethods.range.fn(core),
        )
        return fix

    @api_method
    async def range(core: ClientCore, *, timeout_s: float | None = None) -> float | None:
        """One laser range measurement in metres (None: the rangefinder reported no distance)."""
        checks.positive_seconds("timeout_s", timeout_s)
        spec = roles.command(core.dialect, core.model, "range")
        if spec is None or (not spec.readable and core.model.lrf_range_m is None):
            raise UnsupportedError(f"the {core.model.name} has no laser rangefinder")
        if spec.readable:  # a query answers with the distance (SkyDroid SLR)
            d = fields_of(await request(core, spec.ident, read=True, timeout_s=timeout_s)).get("distance_m")
            core.state.set("range_m", d)
            return float(d) if isinstance(d, (int, float)) else None
        ident = spec.ident  # a control whose result comes as a report (TOPOTEK LRF)
        result: asyncio.Future[float | None] = asyncio.get_running_loop().create_future()

        def on_result(m: Message) -> None:
            if m.fields and "distance_m" in m.fields and not result.done():
                result.set_result(m.fields["distance_m"])

        unsubscribe = core.subscribe(on_result, ident)
        try:
            await request(core, ident, action="single", timeout_s=timeout_s)
            wait = (timeout_s or core.timeout_s) * 3
            try:
                return await within(result, wait)
            except asyncio.TimeoutError:
                raise RequestTimeoutError(f"the rangefinder sent no result within {wait:.1f} s") from None
        finally:
            unsubscribe()

    @api_method
    async def network(core: ClientCore) -> dict[str, str | None]:
        """The camera's network settings (IP, gateway, and DNS where the model has them)."""
        out: dict[str, str | None] = {}
        for name, role in NETWORK:
            spec = roles.readable(core.dialect, core.model, role)
            if spec is not None:
                address = fields_of(await request(core, spec.ident, read=True)).get("address")
                out[name] = None if address is None else str(address)
        return out

    @api_method
    async def set_network(
        core: ClientCore,
        ip: str | None = None,
        gateway: str | None = None,
        dns: str | None = None,
        backup_dns: str | None = None,
    ) -> None:
        """Change network settings (all checked first). After `ip` changes, the camera answers at the
        new address."""
        wanted = {"ip": ip, "gateway": gateway, "dns": dns, "backup_dns": backup_dns}
        plan = []
        for name, role in NETWORK:
            if wanted[name] is not None:
                plan.append((roles.require_role(core.dialect, core.model, role, f"{name} setting"), wanted[name]))
        for ident, v in plan:
            core.build(ident, address=v)
        for ident, v in plan:
            await request(core, ident, address=v)


# The methods' own calls to each other (and the other api_* modules'): the plain functions.
digital_zoom = CameraMethods.digital_zoom.fn
