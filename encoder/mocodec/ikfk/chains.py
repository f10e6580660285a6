"""Motion chains (seed 000 §3.1, §5.1): paths from the root to an end effector.

The seed names CMU's chains (trunk, two arms, two legs) but gives no rule. Ours, for any
skeleton, works on rest-pose geometry only, so encoder and decoder derive the same chains:

1. The *reach* of a node is the largest rest-pose distance from it to any node of its
   subtree. A child's subtree is a *limb* when the child's offset plus its reach (an upper
   bound of the subtree's extent seen from the branching node) is at least ``min_reach`` × the
   skeleton's height (default 0.2: arms and legs qualify, fingers, thumbs and toes do not).
2. Every limb hanging off the root starts a chain. Walking down a chain, at a node with
   several children the chain continues into the child that best keeps the incoming bone's
   direction (the trunk goes on into the neck, not into a shoulder); every other child that is
   a limb starts a new chain, which shares the path from the root down to that node (chains
   run root → effector, as in eq. 17). Smaller side branches (thumbs) belong to no chain.
3. A chain ends at a leaf (an End Site when the file has one): the end effector.

Zero-length offsets (CMU's hip and shoulder joints) stay in the node path but give no link.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion import Skeleton
from ..units import skeleton_height

_ZERO = 1e-12


@dataclass(frozen=True)
class Chain:
    """One motion chain: ``nodes`` root → end effector; ``links`` the (parent, child) pairs of
    consecutive nodes with a non-zero rest offset, each contributing L_j d_j in eq. 18."""

    nodes: tuple[int, ...]
    links: tuple[tuple[int, int], ...]

    @property
    def effector(self) -> int:
        return self.nodes[-1]

    def lengths(self, skeleton: Skeleton) -> np.ndarray:
        """Link lengths L_j (rigid: the child's rest offset norm)."""
        return np.array([np.linalg.norm(skeleton.offsets[c]) for _, c in self.links])


def subtree_reach(skeleton: Skeleton) -> np.ndarray:
    """Per node, the largest rest-pose distance to a node of its subtree (0 for leaves)."""
    n = skeleton.node_count
    rest = np.zeros((n, 3))
    for i, p in enumerate(skeleton.parents):
        rest[i] = skeleton.offsets[i] + (rest[p] if p >= 0 else 0.0)
    reach = np.zeros(n)
    for i in range(n):
        desc = skeleton.descendants(i)
        if desc:
            reach[i] = float(np.linalg.norm(rest[desc] - rest[i], axis=-1).max())
    return reach


def motion_chains(skeleton: Skeleton, min_reach: float = 0.2) -> list[Chain]:
    """The motion chains of ``skeleton`` by the rule in the module docstring, one per root
    limb and per limb branching off a chain, in discovery order."""
    height = skeleton_height(skeleton)
    reach = subtree_reach(skeleton)
    # A child subtree's reach seen from its parent includes the child's own offset.
    child_reach = np.array([reach[i] + np.linalg.norm(skeleton.offsets[i])
                            for i in range(skeleton.node_count)])
    is_limb = child_reach >= min_reach * height
    chains: list[Chain] = []
    # Each pending start: (path from the root so far, child to continue into).
    pending = [([int(r)], c) for r in np.flatnonzero(skeleton.parents < 0)
               for c in skeleton.children(int(r)) if is_limb[c]]
    while pending:
        path, node = pending.pop(0)
        path = path + [node]
        while True:
            kids = skeleton.children(node)
            if not kids:
                break
            nxt = _straight_on(skeleton, path, kids, reach)
            for c in kids:
                if c != nxt and is_limb[c]:
                    pending.append((list(path), c))
            path.append(nxt)
            node = nxt
        links = tuple((a, b) for a, b in zip(path[:-1], path[1:])
                      if np.linalg.norm(skeleton.offsets[b]) > _ZERO)
        chains.append(Chain(tuple(path), links))
    return chains


def _straight_on(skeleton: Skeleton, path: list[int], kids: list[int], reach: np.ndarray) -> int:
    """The child that best continues the last non-zero bone of ``path`` (rest pose); with no
    such bone, or only zero-length children, the child with the largest reach."""
    if len(kids) == 1:
        return kids[0]
    incoming = next((skeleton.offsets[n] for n in reversed(path)
                     if np.linalg.norm(skeleton.offsets[n]) > _ZERO), None)
    # Rest direction into each child's subtree: its offset, or through zero-length children
    # the direction to the first descendant (following first children) at a non-zero distance.
    dirs = np.array([_rest_direction(skeleton, c) for c in kids])
    if incoming is None or not np.any(np.linalg.norm(dirs, axis=-1) > 0):
        return kids[int(np.argmax([reach[c] for c in kids]))]
    cos = dirs @ (incoming / np.linalg.norm(incoming))
    return kids[int(np.argmax(cos))]


def _rest_direction(skeleton: Skeleton, node: int) -> np.ndarray:
    """Unit rest direction from ``node``'s parent into its subtree (zero if none)."""
    v = skeleton.offsets[node].copy()
    cur = node
    while np.linalg.norm(v) <= _ZERO:
        kids = skeleton.children(cur)
        if not kids:
            return np.zeros(3)
        cur = kids[0]
        v = v + skeleton.offsets[cur]
    return v / np.linalg.norm(v)
