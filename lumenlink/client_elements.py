"""`lumenlink.Client`'s calls for optical files (ray files, measured BRDFs) and elements with an inside (add,
place, switch, pack, design). A mixin: the connection, the scene lookup and the errors are `Client`'s."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from lumenlink.client_base import ClientBase
from lumenlink.client_values import triples
from lumenlink.errors import LumenLinkError


class ElementCalls(ClientBase):
    """Optical files and elements with an inside (`Client` is made of it)."""

    # ------------------------------------------------------------ optical files (ray files, BRDF tables)

    def upload_optical_file(self, path: str | Path, format: str | None = None) -> dict[str, Any]:  # noqa: A002
        """Upload a ray file or a measured BRDF table once (``POST /optical-files``), streamed from disk; answers
        ``{id, format, bytes, ...}``. Name it by its id in a light (``{"type": "rayfile", "file": id, ...}``) or a
        material (``{"type": "measured_brdf", "file": id}``). `format`: ``tm25``, ``rays`` (text columns) or
        ``brdf``; by default TM-25 where the file begins with ``TM25``, a BRDF table where its first words name
        ``theta_i_deg``, else a text ray file."""
        p = Path(path)
        if not p.is_file():
            raise LumenLinkError(f"no file {str(p)!r} to upload", usage=True)
        fmt = format or _optical_format(p)

        def chunks():
            with open(p, "rb") as fh:
                while block := fh.read(1 << 20):
                    yield block
        return dict(self._call("POST", "/optical-files", f"uploading {p.name}", params={"format": fmt},
                               content=chunks(), headers={"Content-Type": "application/octet-stream"}))

    def optical_files(self) -> list[dict[str, Any]]:
        """Every uploaded optical file's summary."""
        return list(self._call("GET", "/optical-files", "listing optical files"))

    # ------------------------------------------------------------ elements with an inside

    def add_element(self, body: dict[str, Any]) -> dict[str, Any]:
        """Prepare an element into the library (docs/DESIGN.md "Optical elements with an inside"): answers ``{id,
        features, bytes, prepare_seconds}``; the same body answers the same id, preparing nothing."""
        if not isinstance(body, dict):
            raise LumenLinkError("an element is a JSON object {\"type\": \"microstructure\", \"feature\", "
                                 "\"layout\"}", usage=True)
        return dict(self._call("POST", "/elements", "preparing an element", json=body))

    def elements(self) -> list[dict[str, Any]]:
        """The library: every prepared element with its size and preparation time."""
        return list(self._call("GET", "/elements", "listing the element library"))

    def put_element(self, scene: str | dict, path_or_uuid: str, element: str | dict[str, Any], *,
                    facing: Sequence[float] | None = None, faces: Sequence[int] | None = None,
                    model: str | None = None) -> dict[str, Any]:
        """Put an element (its library id, or a body, prepared first) onto the faces of a node that face `facing`
        (its own frame), or onto its B-rep `faces`; `model` "exact" (default) or "bsdf" (its tabulated BSDF). Answers
        ``{id, body, orphaned, applied, problem, model, support}``."""
        eid = element if isinstance(element, str) else self.add_element(element)["id"]
        body: dict[str, Any] = {"element": eid, "node": path_or_uuid}
        if facing is not None:
            body["facing"] = triples([list(facing)], "facing")[0]
        if faces is not None:
            body["faces"] = [int(f) for f in faces]
        if model is not None:
            body["model"] = model
        return dict(self._call("POST", f"/scenes/{self._sid(scene)}/elements", f"putting an element on "
                                                                              f"{path_or_uuid!r}", json=body))

    def scene_elements(self, scene: str | dict) -> list[dict[str, Any]]:
        return list(self._call("GET", f"/scenes/{self._sid(scene)}/elements", "listing the scene's elements"))

    def remove_element(self, scene: str | dict, assignment: str) -> None:
        """Take an element off its part (the part's faces are plain again)."""
        self._call("DELETE", f"/scenes/{self._sid(scene)}/elements/{assignment}", "taking an element off")

    def switch_element(self, scene: str | dict, assignment: str, element: str) -> dict[str, Any]:
        """Switch an element assignment to another library element in one call (a packed pattern, say)."""
        return dict(self._call("PUT", f"/scenes/{self._sid(scene)}/elements/{assignment}", "switching an element",
                               json={"element": element}))

    def pack(self, element: str, scene: str | dict, assignment: str, sensor: str, *, wait: bool = True,
             progress: Callable[[dict[str, Any]], None] | None = None, poll: float = 0.5,
             **options: Any) -> dict[str, Any]:
        """Pack a density element against the grid `sensor` over the lit face of the part that `assignment` puts it
        on (``POST /elements/{id}/pack``); options: target, figure, photons, max_photons, max_iterations,
        max_seconds, damping, max_fill, pitch_mm, seed, quantity ("illuminance" or "luminance"), distance,
        aperture_deg. With `wait`, follows the job (Ctrl-C cancels it; a cancelled
        pack keeps what it measured) and answers its last state, whose ``result`` names the packed ``element``;
        otherwise the 202 answer (``url``). `sensor`: the grid's id or its name."""
        sid = self._sid(scene)
        if sensor == "all":
            raise LumenLinkError("a pack measures one grid sensor: name it (its id or its name), not 'all'",
                                 usage=True)
        body = {"scene": sid, "assignment": assignment, "sensor": self._sensor_ids(sid, sensor)[0]["id"], **options}
        accepted = dict(self._call("POST", f"/elements/{element}/pack", "starting a pack", ok=(202,), json=body))
        if not wait:
            return accepted
        return self.follow(accepted["url"], progress=progress, poll=poll)

    def design(self, element: str, scene: str | dict, assignment: str, sensor: str,
               parameters: list[dict[str, Any]], *, objective: str = "min_max", wait: bool = True,
               progress: Callable[[dict[str, Any]], None] | None = None, poll: float = 0.5,
               **options: Any) -> dict[str, Any]:
        """Tune one to three numbers of an element (``POST /elements/{id}/design``: `parameters` as ``[{"name":
        "feature.height_mm", "values": [...]}]`` or ``{"name", "lo", "hi", "steps"}``) against `objective` ("min_max",
        "min_mean" or "mean" read on the grid `sensor`, or "half_angle": the viewing-angle spread of its centre,
        degrees); options as `pack` takes them, ``goal`` ("max", or "min" to lower the objective), and `pack_map` (pack
        the density map before and after the sweep). With `wait`, follows the job (Ctrl-C cancels it, keeping the best
        read so far) and answers its last state, whose ``result`` names the chosen ``element``, its ``values`` and the
        ``confirmation`` on a fresh seed; otherwise the 202 answer (``url``)."""
        sid = self._sid(scene)
        body = {"scene": sid, "assignment": assignment, "sensor": self._sensor_ids(sid, sensor)[0]["id"],
                "parameters": parameters, "objective": objective, **options}
        accepted = dict(self._call("POST", f"/elements/{element}/design", "starting a design loop", ok=(202,),
                                   json=body))
        if not wait:
            return accepted
        return self.follow(accepted["url"], progress=progress, poll=poll)

    def design_record(self, element: str) -> dict[str, Any]:
        """How a designed element was found: its values, the baseline, every candidate, the confirmation."""
        return dict(self._call("GET", f"/elements/{element}/design", "reading a design loop's record"))

    def design_png(self, element: str) -> bytes:
        """A designed element's ``design.png``: each candidate's objective ± error, the start, the chosen one."""
        return self._bytes(f"/elements/{element}/design.png", f"reading the design plot of {element}")

    def pack_record(self, element: str) -> dict[str, Any]:
        """How a packed element was found: target, stop, history (uniformity ± error and seconds per iteration)."""
        return dict(self._call("GET", f"/elements/{element}/pack", "reading a pack's history"))

    def pack_png(self, element: str) -> bytes:
        """A packed element's ``pack.png``: density map, the map it measured, uniformity against iterations."""
        return self._bytes(f"/elements/{element}/pack.png", f"reading the pack plot of {element}")


ZEMAX_HEADS = ("Source", "Symmetry", "SpectralContent", "ScatterType", "SampleRotation", "AngleOfIncidence")


def _optical_format(path: Path) -> str:
    """An optical file's format from its first bytes: ``tm25``, ``brdf`` or ``rays``."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if head[:4] == b"TM25":
        return "tm25"
    words = [line.split("#", 1)[0].split() for line in head.decode("utf-8", errors="replace").splitlines()]
    first = next((w[0] for w in words if w), "")
    return "brdf" if first in ("theta_i_deg", "theta_o_deg", "dphi_deg") + ZEMAX_HEADS else "rays"
