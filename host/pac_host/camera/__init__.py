"""The overhead camera: fiducial markers on the floor and on the robot (OpenCV's ArUco).

- :mod:`layout`: what is printed and where it lies (floor markers, the robot's marker, the
  lens-calibration board);
- :mod:`geometry`: the pinhole camera with lens distortion (projection, pixel rays);
- :mod:`render`: a virtual camera that draws frames of the floor and the robot (tests, demo);
- :mod:`detect`: markers in a frame, and the robot's pose from its marker;
- :mod:`calibrate`: the floor homography, the camera's position and the lens, in one file;
- :mod:`sources`: frames from a camera, a video, a folder or the virtual camera;
- :mod:`observer`: the ``camera:`` observer (poses over each gait cycle's listening window);
- :mod:`rig`: several cameras on one floor frame, their poses fused or handed over;
- :mod:`plan`: how many cameras a long area needs, where, and the floor markers for them;
- :mod:`serve`: the same detection as a ``POSE`` stream for the ``tracker:`` observer;
- :mod:`sheets`, :mod:`draw`: printable sheets and the check image.
"""
