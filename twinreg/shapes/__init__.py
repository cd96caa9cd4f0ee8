"""A shape for every object (issue 36): the members of a type without a decided model co-registered through their
sections, their points fused in the type's frame (mirrored, or turned about the axis, as the type's symmetry
allows) and meshed (:mod:`.fuse`); each member placed with its type's shape; the shape's quality."""
