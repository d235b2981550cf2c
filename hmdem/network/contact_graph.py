"""Network = faces of the planar contact graph of a disc packing (seed 004 §2.1; digest §3, §15.2).

A domain is a bounded face of the graph whose vertices are grain centres and whose edges are
grain-grain contacts; a pipe sits at each contact. Built as in digest §15.2 item 5: Delaunay
triangles of the centres are glued across Delaunay edges that are *not* contacts; each glued
region that does not reach the convex hull through a non-contact edge is one domain. Domain
volume is the full centre-polygon area x 1 m (digest §3.3).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, cKDTree

from .network import OUTSIDE, Network

# pairs closer than this fraction of the smaller radius are pipes: the Lenormand packing's
# network then has the paper's size (decisions #2); the Huang sample's keeps it (#17, #73)
NEAR_CONTACT_GAP = 0.08


def find_contacts(centres: np.ndarray, radii: np.ndarray, tolerance: float = 1e-3) -> np.ndarray:
    """Pairs (i < j) of discs whose gap is at most ``tolerance`` x the smaller radius."""
    tree = cKDTree(centres)
    pairs = tree.query_pairs(2.0 * radii.max() * (1 + tolerance), output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), int)
    i, j = pairs[:, 0], pairs[:, 1]
    dist = np.linalg.norm(centres[i] - centres[j], axis=1)
    gap = dist - radii[i] - radii[j]
    keep = gap <= tolerance * np.minimum(radii[i], radii[j])
    return np.sort(pairs[keep], axis=1)


def main_component(n_grains: int, contacts: np.ndarray) -> np.ndarray:
    """Contacts of the largest connected cluster; floating clusters and rattlers are dropped."""
    graph = coo_matrix((np.ones(len(contacts)), (contacts[:, 0], contacts[:, 1])), shape=(n_grains, n_grains))
    _, label = connected_components(graph, directed=False)
    sizes = np.bincount(label[contacts[:, 0]], minlength=label.max() + 1)
    return contacts[label[contacts[:, 0]] == np.argmax(sizes)]


def delaunay_edge_keys(simplices: np.ndarray, n: int) -> np.ndarray:
    """(t, 3) keys i * n + j (i < j) of each triangle's edges, edge k opposite vertex k."""
    ea, eb = simplices[:, [1, 2, 0]], simplices[:, [2, 0, 1]]
    return np.minimum(ea, eb).astype(np.int64) * n + np.maximum(ea, eb)


class ContactsOffTriangulation(ValueError):
    """Contacts that are not edges of the centres' Delaunay triangulation."""


def check_contacts_on_triangulation(contacts: np.ndarray, edge_keys: np.ndarray, n: int) -> None:
    """A :class:`ContactsOffTriangulation` if some contacts (i < j) are not Delaunay edges
    (``edge_keys`` from :func:`delaunay_edge_keys`): a grain sits in their throat, and the
    network, whose pipes are Delaunay edges, would lose them and merge the two pores they
    separate while the Euler check still passed (found in review). None in the shipped packings,
    with their near contacts up to a gap of 0.38 too."""
    missing = ~np.isin(contacts[:, 0].astype(np.int64) * n + contacts[:, 1], edge_keys)
    if missing.any():
        i, j = contacts[np.argmax(missing)]
        count = int(missing.sum())
        raise ContactsOffTriangulation(
            f"{count} of its contacts (e.g. grains {i} and {j}) {'are not edges' if count > 1 else 'is not an edge'} "
            "of the centres' Delaunay triangulation: a grain sits in the throat, and the pore network cannot have "
            f"{'them' if count > 1 else 'it'} as a pipe")


def check_packing_contacts(centres: np.ndarray, contacts: np.ndarray) -> None:
    """:func:`check_contacts_on_triangulation` for a packing's own contact pairs (any order)."""
    n = len(centres)
    check_contacts_on_triangulation(np.sort(contacts, axis=1), delaunay_edge_keys(Delaunay(centres).simplices, n), n)


def _triangle_areas(points: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    a, b, c = points[simplices[:, 0]], points[simplices[:, 1]], points[simplices[:, 2]]
    return 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))


def build_contact_network(centres: np.ndarray, radii: np.ndarray, contacts: np.ndarray) -> Network:
    """Build domains and pipes from disc centres, radii and contact pairs.

    ``pipe_domains[:, 0]`` is the face to the left of the directed segment from
    ``pipe_grains[:, 0]`` to ``pipe_grains[:, 1]`` (needed for the grain forces of Eq. 8).

    Pipes have length r1 + r2 (seed 004 Eq. 1); apertures are left at zero for the caller
    (fixed grains: :func:`hmdem.network.apertures.uniform_apertures`). Contacts of clusters not
    connected to the main contact graph are dropped so that the Euler check holds. A contact
    that is not a Delaunay edge is a :class:`ContactsOffTriangulation`
    (:func:`check_contacts_on_triangulation`).
    """
    centres = np.asarray(centres, float)
    radii = np.asarray(radii, float)
    n = len(centres)
    contacts = main_component(n, np.sort(np.asarray(contacts, int), axis=1))
    contact_keys = contacts[:, 0].astype(np.int64) * n + contacts[:, 1]

    tri = Delaunay(centres)
    simp, nbr = tri.simplices, tri.neighbors
    n_tri = len(simp)
    keys = delaunay_edge_keys(simp, n)  # triangle edge k is opposite vertex k
    lo, hi = keys // n, keys % n
    check_contacts_on_triangulation(contacts, keys, n)
    is_contact = np.isin(keys, contact_keys)

    # glue triangles across non-contact edges; node n_tri is the outer face
    t_idx = np.repeat(np.arange(n_tri)[:, None], 3, axis=1)
    glue = ~is_contact
    src = t_idx[glue]
    dst = np.where(nbr[glue] >= 0, nbr[glue], n_tri)
    graph = coo_matrix((np.ones(len(src)), (src, dst)), shape=(n_tri + 1, n_tri + 1))
    _, comp = connected_components(graph, directed=False)
    outer = comp[n_tri]
    labels, tri_domain = np.unique(comp[:n_tri], return_inverse=True)
    tri_domain = tri_domain.ravel()
    is_outer_label = labels == outer
    # renumber domains so that the outer face is OUTSIDE
    remap = np.cumsum(~is_outer_label) - 1
    remap[is_outer_label] = OUTSIDE
    tri_domain = remap[tri_domain]
    n_domains = int((~is_outer_label).sum())

    area = _triangle_areas(centres, simp)
    tri_centroid = centres[simp].mean(axis=1)
    inside = tri_domain != OUTSIDE
    volume = np.bincount(tri_domain[inside], weights=area[inside], minlength=n_domains)
    centroid = np.stack(
        [np.bincount(tri_domain[inside], weights=area[inside] * tri_centroid[inside, k], minlength=n_domains) for k in (0, 1)],
        axis=1,
    ) / volume[:, None]

    # one pipe per contact edge of the triangulation; sides from the two adjacent triangles
    side_a = tri_domain[t_idx]
    side_b = np.where(nbr >= 0, tri_domain[np.maximum(nbr, 0)], OUTSIDE)
    first = is_contact & ((nbr < 0) | (t_idx < nbr))  # visit each edge once
    pipe_grains = np.stack([lo[first], hi[first]], axis=1)
    pipe_domains = np.stack([side_a[first], side_b[first]], axis=1)
    # orient: pipe_domains[:, 0] lies to the left of grain 0 -> grain 1 (the triangle's third vertex)
    tri_of_edge, opposite = first.nonzero()  # edge k of a triangle is opposite its vertex k
    x0, x1, x3 = centres[lo[first]], centres[hi[first]], centres[simp[tri_of_edge, opposite]]
    cross = (x1[:, 0] - x0[:, 0]) * (x3[:, 1] - x0[:, 1]) - (x1[:, 1] - x0[:, 1]) * (x3[:, 0] - x0[:, 0])
    pipe_domains[cross < 0] = pipe_domains[cross < 0][:, ::-1]
    order = np.lexsort((pipe_grains[:, 1], pipe_grains[:, 0]))
    pipe_grains, pipe_domains = pipe_grains[order], pipe_domains[order]
    pipe_length = radii[pipe_grains[:, 0]] + radii[pipe_grains[:, 1]]

    return Network(
        domain_centroid=centroid,
        domain_volume=volume * 1.0,  # x 1 m out-of-plane depth
        pipe_domains=pipe_domains.astype(int),
        pipe_length=pipe_length,
        pipe_aperture=np.zeros(len(pipe_length)),
        pipe_grains=pipe_grains.astype(int),
        points=centres,
        triangles=simp,
        triangle_domain=tri_domain,
        triangle_neighbors=nbr,
        n_vertices=len(np.unique(pipe_grains)),
        extent=(centres[:, 0].min() - radii.max(), centres[:, 0].max() + radii.max(),
                centres[:, 1].min() - radii.max(), centres[:, 1].max() + radii.max()),
    )


# how a coupled run holds the hull grains: in place (seed 004's sealed cell edges), or as pistons
# under the constant force that held them at the start (DiscAssembly.release_along); here, not in
# hmdem.coupling.radial, so that the command line's parser does not import the coupling
BOUNDARY_HOLDS = ("fixed", "loaded")


def hull_grains(net: Network) -> np.ndarray:
    """Mask of the grains on the outer boundary of the contact graph: both grains of every contact
    that borders the outer face (the sample's boundary grains)."""
    mask = np.zeros(len(net.points), bool)
    mask[net.pipe_grains[(net.pipe_domains == OUTSIDE).any(axis=1)].ravel()] = True
    return mask


def boundary_domains(net: Network) -> np.ndarray:
    """Domains that share a triangulation edge with the outer face (they touch the sample edge)."""
    nbr = net.triangle_neighbors
    nbr_dom = np.where(nbr >= 0, net.triangle_domain[np.maximum(nbr, 0)], OUTSIDE)
    own = np.repeat(net.triangle_domain[:, None], 3, axis=1)
    return np.unique(own[(own != OUTSIDE) & (nbr_dom == OUTSIDE)])
