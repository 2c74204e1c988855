"""Model registry: roles built by name from a YAML-like mapping, clear errors otherwise."""
from __future__ import annotations

import pytest

from lomanip_perception import registry
from lomanip_perception.errors import INVALID_REQUEST, MODEL_UNAVAILABLE, PerceptionError
from lomanip_perception.roles import (ROLES, DepthEstimator, HumanPoseEstimator, ImageGenerator, ObjectDetector,
                                      Segmenter, SemanticMatcher)


def test_default_is_synthetic_for_every_role_and_fits_the_protocols():
    models = registry.build_models({})
    assert models.names() == {r: "synthetic" for r in ROLES}
    for obj, proto in [(models.image_generator, ImageGenerator), (models.detector, ObjectDetector),
                       (models.segmenter, Segmenter), (models.depth_estimator, DepthEstimator),
                       (models.matcher, SemanticMatcher), (models.pose_estimator, HumanPoseEstimator)]:
        assert isinstance(obj, proto)


def test_params_reach_the_backend():
    models = registry.build_models({"matcher": {"backend": "synthetic", "params": {"outlier_rate": 0.25}},
                                    "depth_estimator": {"params": {"scale_error": 0.2}}})
    assert models.matcher.outlier_rate == 0.25 and models.depth_estimator.scale_error == 0.2


def test_paper_models_fail_with_model_unavailable():
    for role, name in registry.PAPER_MODELS.items():
        assert name in registry.backends(role)
        with pytest.raises(PerceptionError) as e:
            registry.build(role, name)
        # one line that names the role and says which parameter to set
        assert e.value.code == MODEL_UNAVAILABLE and f"({role})" in e.value.message
        assert f"models.{role}." in e.value.message and "\n" not in e.value.message


def test_unknown_backend_role_and_bad_params():
    with pytest.raises(PerceptionError) as e:
        registry.build("matcher", "nope")
    assert e.value.code == INVALID_REQUEST and "synthetic" in e.value.message
    with pytest.raises(PerceptionError) as e:
        registry.build("painter", "synthetic")
    assert e.value.code == INVALID_REQUEST
    with pytest.raises(PerceptionError) as e:
        registry.build("matcher", "synthetic", {"no_such_param": 1})
    assert e.value.code == INVALID_REQUEST and "no_such_param" in e.value.message
    with pytest.raises(ValueError):
        registry.register("painter", "x")


def test_register_a_new_backend():
    class Gen:
        name = "test_gen"

        def __init__(self, k=1):
            self.k = k

        def generate(self, request):
            raise NotImplementedError

    registry.register("image_generator", "test_gen")(Gen)
    try:
        g = registry.build_models({"image_generator": {"backend": "test_gen", "params": {"k": 3}}}).image_generator
        assert g.k == 3 and isinstance(g, ImageGenerator)
    finally:
        registry._REGISTRY["image_generator"].pop("test_gen")
