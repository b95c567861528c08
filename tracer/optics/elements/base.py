"""The element contract: a thin sheet with its own physics, in the paper's sense an optical element.

An element is assigned to a node like a material (``PUT /scenes/{id}/materials/{uuid}``) and keeps the
surface contract (`tracer.optics.surfaces.base`: ``NAME``, ``Spec``, ``row``, ``effects``,
``diffuse_only``, ``albedo``, ``scatter``), with one more promise: it is thin, so a photon crossing it
stays in the medium it was in (``scatter`` never changes ``med`` or ``depth``) and it has no inside
(no ``medium``). Its side is told by the hit's geometric normal: the front is the side it points to. Elements register
in `tracer/optics/surfaces/dispatch.py` beside the surfaces: at a hit they are one switch.
Polarizers and retarders (the polarization issue) join this folder.
"""
