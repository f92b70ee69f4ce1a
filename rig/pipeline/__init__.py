"""The scan pipeline: capture (show, sync, take frames), decode through a codec, triangulate
(dense grids or ring samples), and merge the pairs of a rig into one cloud. It works on an open
Rig and knows nothing of storage, jobs or the web."""
