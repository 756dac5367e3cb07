"""Embedded default dataset: a synthetic actor generated from a seed (no downloaded files).

A face mesh built by code (:mod:`.face_mesh`), 18 Waters-style muscles and a rotating jaw that deform it
non-linearly (:mod:`.muscles`), a performance of expressions and speech (:mod:`.performance`), and a marker take
in the lab with rigid head motion and noise (:mod:`.actor`).
"""

from workbench.dataset.synthetic.actor import HeadMotion, SyntheticTake, make_synthetic_take, synthetic_take_of
from workbench.dataset.synthetic.face_mesh import FaceMesh, face_mesh_of, make_face_mesh
from workbench.dataset.synthetic.muscles import LOWER_FACE, MUSCLE_NAMES, UPPER_FACE, deform, deform_displacements
from workbench.dataset.synthetic.performance import make_activations

__all__ = [
    "FaceMesh",
    "HeadMotion",
    "LOWER_FACE",
    "MUSCLE_NAMES",
    "SyntheticTake",
    "UPPER_FACE",
    "deform",
    "deform_displacements",
    "make_activations",
    "face_mesh_of",
    "make_face_mesh",
    "make_synthetic_take",
    "synthetic_take_of",
]
