"""Optical elements with an inside (the paper's section 4; docs/DESIGN.md "Optical elements with an inside").

A micro-structured face (a light guide's extraction dots, a prism film, a micro-lens array) is a prepared model,
:class:`tracer.elements.microstructure.Microstructure`: its feature shape and its layout, never a mesh. It goes onto
the planar support faces of a part (:mod:`tracer.elements.support`); the part's instance then becomes the bottom-level
kind :mod:`tracer.kinds.relief`, whose intersection traces the support and the features near the ray's path
(:mod:`tracer.elements.features`) inside the element's box.
"""

from tracer.elements.checks import ElementError
from tracer.elements.microstructure import Microstructure, prepare

__all__ = ["ElementError", "Microstructure", "prepare"]
