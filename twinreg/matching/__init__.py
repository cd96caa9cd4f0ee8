"""Matching detected objects to catalogue models (paper 4.3 and beyond): candidates (:mod:`.prefilter`), section
registration and the cluster's shared work (:mod:`.match`), the pose refined on the points (:mod:`.refine`), the
acceptance test (:mod:`.acceptance`) and the decision with its confidence (:mod:`.decision`), each model's prepared
data loaded once (:mod:`.cache`)."""

from .cache import ModelCache
from .match import Match, ObjectMatch, match_objects, placement

__all__ = ["Match", "ModelCache", "ObjectMatch", "match_objects", "placement"]
