import numpy as np
import pytest

from cosco import cluster
from cosco.cluster import check_matrix


def test_threshold_separates_groups():
    d = np.array([[0, .02, .03, .2], [.02, 0, .025, .21], [.03, .025, 0, .19], [.2, .21, .19, 0]])
    res = cluster(d, threshold=0.065)
    assert res.n_clusters == 2
    assert res.labels[0] == res.labels[1] == res.labels[2] != res.labels[3]
    assert cluster(d, threshold=0.01).n_clusters == 4
    assert cluster(d, threshold=1.0).n_clusters == 1


def test_bad_matrices_are_refused():
    with pytest.raises(ValueError, match="square"):
        check_matrix(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="symmetric"):
        check_matrix(np.array([[0, 1], [2, 0]]))


def test_scanned_cars_cluster_with_their_twins(scanned_cars):
    """Two scans of each of three cars fall into three clusters at 4.5 cm (scan-to-scan noise of one car is under
    3.5 cm on these scans; a van and a pick-up are 6.2 cm apart, so the paper's 6.5 cm would join them)."""
    from cosco import describe_object, dissimilarity_matrix

    names = ["vw_beetle_type1", "chrysler_pacifica_2017", "generic_pickup_gazebo"]
    shapes = []
    for n in names:
        pts = scanned_cars[n][0]
        shapes.append(describe_object(pts).sections)
        thinned = pts[np.random.default_rng(1).random(len(pts)) < 0.7]
        shapes.append(describe_object(thinned + [5.0, 5.0, 0.2]).sections)
    res = cluster(dissimilarity_matrix(shapes), threshold=0.045)
    assert res.n_clusters == 3
    assert all(res.labels[2 * i] == res.labels[2 * i + 1] for i in range(3))
