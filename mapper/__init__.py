"""The mapper: depth frames and the camera's pose in, occupancy map deltas out.

Seed 000's "first stage" (Díaz-Toro et al. 2022, §1): 3D points from the Zed Mini's depth
projected to the floor, a height threshold, a global grid merged with the camera's pose.
This package adds the floor found by RANSAC (a chest camera tilts), free space along each
ray (a person who walks away leaves no ghost) and the per-frame proximity that stops the
user before contact. ``birdseye/`` is seed 004's colour-camera map.
"""
