"""A lump is a connected stiff region (evidence.regions, describe.union_of): overlapping lumps of a fit are one."""
import math

import numpy as np
import pytest
from hypothesis import given, settings as hsettings, strategies as st

from palpd.estimate import LumpEstimate
from palpd.learner import describe, evidence, shapes
from palpd.learner.hypotheses import Choice, lumps_claimed


def _theta(kind: str, *lumps) -> tuple[shapes.Family, np.ndarray]:
    family = shapes.Family(kind, len(lumps), 30.0)
    stretch = (math.log(10.0), 0.0) if kind == "ellipses" else ()  # axes R·e^{±ε/2}: 16 x 1.6 mm at R = 5
    params = [[x, y, math.log(r), *stretch, 0.0, math.log(4.0), 0.0] for x, y, r in lumps]
    return family, np.array([0.0, 0.0, 0.0, *np.concatenate(params)])


@pytest.mark.parametrize("kind, lumps, regions", [
    ("circles", [(0, 0, 5), (12, 0, 5)], [[0], [1]]),             # 2 mm apart edge to edge: two lumps
    ("circles", [(0, 0, 5), (9, 0, 5)], [[0, 1]]),                # overlapping by 1 mm: one region
    ("circles", [(0, 0, 5), (20, 0, 5), (10, 0, 6)], [[0, 1, 2]]),   # a chain: the middle one joins the ends
    ("circles", [(0, 0, 5), (20, 0, 5), (40, 0, 3)], [[0], [1], [2]]),
    ("ellipses", [(0, 0, 5), (6, 0, 5)], [[0, 1]]),              # end to end along their axes
    ("ellipses", [(0, 0, 5), (0, 4, 5)], [[0], [1]]),            # side by side 4 mm apart
])
def test_lumps_whose_boundaries_overlap_are_one_region(kind, lumps, regions):
    family, theta = _theta(kind, *lumps)
    assert evidence.regions(family, theta) == regions


def _cov(family: shapes.Family, centre_sd: float, log_radius_sd: float) -> np.ndarray:
    """A diagonal covariance: each lump's centre and log radius at these sds, the rest pinned."""
    var = np.full(family.size, 1e-12)
    for j in range(family.k):
        start = family.lump_slice(j).start
        var[start:start + 2] = centre_sd**2
        var[start + 2] = log_radius_sd**2
    return np.diag(var)


def test_lumps_whose_boundaries_nearly_meet_are_one_region_or_two_by_their_sds():
    """The count over the parameters' posterior, not at the mode: the fit a triangle's active scan ended on (a
    disc and a small one in its corner, their boundaries 0.45 mm apart) was counted two at weight 1.000."""
    family, theta = _theta("circles", (0, 0, 5), (10.45, 0, 5))
    unsure = evidence.region_counts(family, theta, _cov(family, 0.5, 0.03))
    assert set(unsure) == {1, 2} and min(unsure.values()) > 0.1 and sum(unsure.values()) == pytest.approx(1.0)
    assert evidence.region_counts(family, theta, _cov(family, 0.5, 0.03)) == unsure  # the same readings, the same answer
    assert evidence.region_counts(family, theta, _cov(family, 0.01, 0.001)) == {2: 1.0}  # sure: apart
    family, theta = _theta("circles", (0, 0, 5), (9.5, 0, 5))
    assert evidence.region_counts(family, theta, _cov(family, 0.01, 0.001)) == {1: 1.0}  # sure: overlapping


@hsettings(max_examples=40, deadline=None)
@given(kind=st.sampled_from(["circles", "ellipses"]),
       lumps=st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(1.0, 8.0)), min_size=2, max_size=4),
       centre_sd=st.sampled_from([1e-4, 0.3, 3.0]))
def test_the_count_s_posterior_is_a_distribution_over_counts_that_agrees_with_the_mode_when_sure(kind, lumps,
                                                                                              centre_sd):
    family, theta = _theta(kind, *lumps)
    counts = evidence.region_counts(family, theta, _cov(family, centre_sd, centre_sd / 10.0))
    assert sum(counts.values()) == pytest.approx(1.0) and all(1 <= n <= len(lumps) for n in counts)
    mode = len(evidence.regions(family, theta))
    if centre_sd == 1e-4:  # boundaries sure to 0.4 µm: only a pair meeting that closely could go either way
        assert counts.get(mode, 0.0) >= 0.5


def test_a_hypothesis_counts_its_regions_and_the_count_s_posterior_gathers_them():
    """Two circles laid across one rounded rectangle claim one lump, and weigh for the count of one with
    the ellipse that draws it whole."""
    weights = {"circles:2": 0.6, "ellipse:1": 0.3, "circles:3": 0.1}
    regions = {"circles:2": 1, "circles:3": 2}
    choice = Choice("circles:2", 0.6, "ellipse:1", weights, {1: 0.9, 2: 0.1}, {}, regions)
    assert [choice.count_of(m) for m in ("circles:2", "ellipse:1", "circles:3", "none+soft:1", "free-form", None)] \
        == [1, 1, 2, 0, "free-form", None]
    assert choice.count_weight == pytest.approx(0.9)
    assert [lumps_claimed(m) for m in ("circles:2", "ellipse:3+soft:1", "none")] == [2, 3, 0]


def _disc(centre, radius, sd=0.1) -> LumpEstimate:
    angle = np.linspace(0.0, 2 * math.pi, 181)
    boundary = np.column_stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)])
    boundary[-1] = boundary[0]
    return LumpEstimate(tuple(centre), radius, sd, sd, boundary.tolist(), depth_mm=2.0, depth_sd_mm=0.5)


def _lens_mm2(d: float, r1: float, r2: float) -> float:
    """The area two discs share (the textbook lens), d between centres, 0 < d < r1 + r2."""
    a1 = r1 * r1 * math.acos((d * d + r1 * r1 - r2 * r2) / (2 * d * r1))
    a2 = r2 * r2 * math.acos((d * d + r2 * r2 - r1 * r1) / (2 * d * r2))
    return a1 + a2 - 0.5 * math.sqrt((-d + r1 + r2) * (d + r1 - r2) * (d - r1 + r2) * (d + r1 + r2))


@hsettings(max_examples=30, deadline=None)
@given(r1=st.floats(2.0, 12.0), r2=st.floats(2.0, 12.0), overlap=st.floats(0.1, 0.9))
def test_a_union_of_overlapping_discs_is_reported_by_its_outline_area_and_centroid(r1, r2, overlap):
    """union_of: the equal-area radius is the union's (the two discs less their lens), the centroid the
    area-weighted one on the line between the centres, and the outline holds both centres."""
    d = max(abs(r1 - r2) + 0.05, (r1 + r2) * (1.0 - overlap))
    if d <= abs(r1 - r2) + 1e-9:
        return
    a, b = _disc((0.0, 0.0), r1), _disc((d, 0.0), r2)
    union = describe.union_of([a, b])
    lens = _lens_mm2(d, r1, r2)
    area = math.pi * (r1 * r1 + r2 * r2) - lens
    assert union.radius_mm == pytest.approx(math.sqrt(area / math.pi), rel=0.02, abs=0.05)
    # centroid: each disc's moment less the lens's (the lens's centroid lies between, on the axis)
    assert abs(union.center_mm[1]) < 0.1
    assert 0.0 - 0.1 <= union.center_mm[0] <= d + 0.1
    outline = np.asarray(union.boundary_mm)
    assert np.array_equal(outline[0], outline[-1])
    assert describe.inside_polygon(np.array([[0.0, 0.0], [d, 0.0]]), outline).all()
    assert union.depth_mm == 2.0 and union.edge_mm is None


def test_a_union_on_a_tissue_edge_is_its_part_on_the_tissue():
    a, b = _disc((25.0, 0.0), 8.0), _disc((35.0, 0.0), 8.0)
    union = describe.union_of([a, b], size_mm=(60.0, 60.0))
    outline = np.asarray(union.boundary_mm)
    assert outline[:, 0].max() <= 30.0 + describe.UNION_GRID_MM
    assert union.center_mm[0] < 30.0


def test_the_even_odd_rule_agrees_with_a_disc_and_with_a_c_shaped_polygon():
    disc = np.asarray(_disc((1.0, -2.0), 5.0).boundary_mm)
    points = np.random.default_rng(0).uniform(-8.0, 8.0, (2000, 2))
    inside = describe.inside_polygon(points, disc)
    distance = np.hypot(points[:, 0] - 1.0, points[:, 1] + 2.0)
    clear = np.abs(distance - 5.0) > 0.05  # the 180-gon's sides cut the circle by at most 4 µm... and its vertices
    assert np.array_equal(inside[clear], distance[clear] < 5.0)
    c = np.array([[0, 0], [10, 0], [10, 2], [2, 2], [2, 8], [10, 8], [10, 10], [0, 10], [0, 0]], dtype=float)
    assert describe.inside_polygon(np.array([[1, 5], [5, 5], [5, 1], [5, 9], [11, 5]], dtype=float), c).tolist() \
        == [True, False, True, True, False]


def test_two_circles_across_a_rectangle_are_reported_as_one_lump_its_shape():
    """The fit the active scan of a 24 x 12 mm rounded rectangle ended on (circles:2, their boundaries sharing
    6 % of the smaller's area): one lump, scored against the rectangle as found once, none false, IoU ≥ 0.8."""
    from palpd import metrics
    from palpd.learner.evidence import Fit

    family = shapes.Family("circles", 2, 30.0)
    theta = np.concatenate([[math.log(0.12), 0.0, 0.0], shapes.make_lump((-3.83, -2.55), 6.55, 5.0, 4.0),
                            shapes.make_lump((8.49, -1.31), 7.56, 5.0, 4.0)])
    fit = Fit(family, theta, np.eye(family.size) * 1e-4, 0.01, 0.0, 0.0, True, 40, 0.0)
    assert len(describe.lumps_of(fit)) == 2
    (lump,) = describe.regions_of(fit, describe.parts_of(fit, size_mm=(60.0, 60.0)), (60.0, 60.0))
    corners = np.array([[-9.0, -8.0], [15.0, -8.0], [15.0, 4.0], [-9.0, 4.0], [-9.0, -8.0]])  # square corners: near enough
    truth = [{"center_mm": [3.0, -2.0], "radius_mm": math.sqrt(24 * 12 / math.pi), "boundary_mm": corners.tolist()}]
    m = metrics.compare(truth, [lump.as_dict()], (60.0, 60.0))
    assert (m["lumps_found"], m["false_lumps"]) == (1, 0)
    assert m["min_iou"] >= 0.8 and m["max_center_error_mm"] < 0.6


@pytest.mark.parametrize("centre_sd, decided", [(0.5, False), (0.01, True)])
def test_the_choice_weighs_the_count_over_the_chosen_fit_s_parameters(centre_sd, decided):
    """Hypotheses.choice gathers each hypothesis's count by its draws: the chosen fit alone, two circles whose
    boundaries stand 0.45 mm apart, claims two lumps at its weight of 1.000, but the count's mass on two is
    under the default confidence unless their boundaries are sure to far better than the gap."""
    from palpd.learner.evidence import Fit
    from palpd.learner.hypotheses import Hypotheses

    family, theta = _theta("circles", (0, 0, 5), (10.45, 0, 5))
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    hypotheses.fits = {"circles:2": Fit(family, theta, _cov(family, centre_sd, 0.03 * centre_sd / 0.5), 0.01, 0.0,
                                        0.0, True, 30, 0.0, evidence_checked=True)}
    choice = hypotheses.choice(None, None)
    assert (choice.chosen, choice.weight, choice.count_of("circles:2")) == ("circles:2", 1.0, 2)
    assert sum(choice.counts.values()) == pytest.approx(1.0)
    assert (choice.count_weight >= 0.9) is decided, choice.counts
