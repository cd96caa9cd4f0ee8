"""Recognition in two steps, the paper's hierarchy: an object's kind from the nearest references (:mod:`.kinds`),
then its model within the kind only when the scan decides it (:mod:`.classify`)."""
