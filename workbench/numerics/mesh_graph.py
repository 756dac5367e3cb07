"""The edges of a triangle mesh as a sparse graph: what the RBF's geodesic distances (:mod:`workbench.dataset.rbf`)
and SPLOCS's local supports (:mod:`workbench.numerics.alternatives`) walk along."""

from __future__ import annotations

import numpy as np


def mesh_edge_graph(vertices: np.ndarray, triangles: np.ndarray):
    """Sparse symmetric graph of the mesh's edges, weighted by their lengths.

    Returns
    -------
    scipy.sparse.csr_matrix of shape (n_vertices, n_vertices)
    """
    from scipy.sparse import coo_matrix

    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    n = len(vertices)
    graph = coo_matrix(
        (
            np.concatenate([lengths, lengths]),
            (np.concatenate([edges[:, 0], edges[:, 1]]), np.concatenate([edges[:, 1], edges[:, 0]])),
        ),
        shape=(n, n),
    )
    return graph.tocsr()
