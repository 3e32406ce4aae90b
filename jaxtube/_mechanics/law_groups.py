"""Joints grouped by the structure of their tubes' laws, so that each group's laws are
evaluated (and differentiated) once for all its joints, not once per tube.

A kite has many tubes (the V3 kite: 11, 87 joints) and usually one law form for all of them,
each tube with its own parameters (pressure, a fitted factor). Evaluating the laws tube by
tube put one copy of the law, the joint rotation and their second derivatives into the
compiled program per tube, and one small kernel per copy into every Newton step. Here the
tubes whose bending laws and torsion laws have the same PyTree structure (the same types and
static fields, leaves of the same shapes) form one group: their laws' leaves are stacked and
taken per joint, and the law is evaluated under ``jax.vmap`` over the group's joints. A
group of one tube (a single tube, or a tube with a law form of its own) calls its law
directly, as before. The values are the same; only the order of a sum over joints changes.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .geometry import take_rows


class LawGroup(NamedTuple):
    """Joints whose tubes' laws share one PyTree structure.

    Attributes:
        joints: ``[Jg]`` int, the group's joints (ascending).
        tubes: ``[Jg]`` int, each joint's tube.
    """

    joints: np.ndarray
    tubes: np.ndarray

    @property
    def one_tube(self) -> bool:
        return bool(np.all(self.tubes == self.tubes[0]))

    def per_joint(self, values):
        """A per-tube array ``[T, ...]`` for the group: the one tube's row, or ``[Jg, ...]``."""
        if self.one_tube:
            return values[int(self.tubes[0])]
        return take_rows(values, self.tubes)

    def law(self, laws):
        """The group's law: the one tube's law, or the laws of its tubes with every leaf
        stacked and taken per joint (leaves ``[Jg, ...]``, for :meth:`law_axis` ``0``)."""
        if self.one_tube:
            return laws[int(self.tubes[0])]
        unique = np.unique(self.tubes)
        member = np.searchsorted(unique, self.tubes)

        def stacked(*leaves):
            leaf = jnp.stack([jnp.asarray(x) for x in leaves])
            if jnp.issubdtype(leaf.dtype, jnp.floating):
                return take_rows(leaf, member)
            return leaf[member]

        return jax.tree.map(stacked, *[laws[int(t)] for t in unique])

    @property
    def law_axis(self):
        """``jax.vmap`` axis of :meth:`law` and :meth:`per_joint` values: ``None`` (one tube)
        or ``0``."""
        return None if self.one_tube else 0

    def apply(self, law, method: str, *args):
        """``law.method(*args)`` for the group's joints (``args`` with a leading ``[Jg]``
        axis, or per-tube values from :meth:`per_joint`)."""
        if self.one_tube:
            return getattr(law, method)(*args)
        return jax.vmap(lambda lw, *a: getattr(lw, method)(*a))(law, *args)


def _law_key(law):
    leaves, treedef = jax.tree.flatten(law)
    return treedef, tuple((np.shape(x), str(jnp.result_type(x))) for x in leaves)


def law_groups(law_tube, bending_laws, torsion_laws) -> list[LawGroup]:
    """The joints (tube of each: ``law_tube`` ``[J]``) grouped by the PyTree structure of
    their tubes' bending and torsion laws, in order of first appearance."""
    law_tube = np.asarray(law_tube, dtype=np.int32).reshape(-1)
    tube_key = {int(t): (_law_key(bending_laws[int(t)]), _law_key(torsion_laws[int(t)]))
                for t in np.unique(law_tube)}
    groups: dict = {}  # (insertion order: first appearance)
    for j, tube in enumerate(law_tube):
        groups.setdefault(tube_key[int(tube)], []).append(j)
    return [LawGroup(np.array(js, dtype=np.int32), law_tube[np.array(js, dtype=np.int32)])
            for js in groups.values()]
