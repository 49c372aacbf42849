"""Names shared by every interop format (docs/interop.md): frames, topics, stream names."""

CORE_FRAME = ("pito_core: the PITO core frame, origin at the centre of the cube, axes along the face normals "
              "(face 1 +x, 2 +y, 3 -x, 4 -y, 5 +z, 6 -z), m")
FACE_FRAME = ("face {i}'s frame (pito_face_{i}: origin at the centre of face {i}, z along its outward normal; "
              "docs/conventions.md)")
ROS_CORE_FRAME = "pito_core"
ROS_FACE_FRAME = "pito_face_{i}"
WRENCH_STREAM = "pito-wrenches"
WRENCH_TYPE = "Force"
CONTACT_STREAM = "pito-contacts"
CONTACT_TYPE = "Contact"
#: Per face, the 12 channels of ``pito-contacts``: (label suffix, unit, type). ``single``: 1 where
#: one fingertip on the patch can produce the face's wrench (``ContactEstimate.single_contact``), 0
#: where not (a valid contact with ``single`` 0 is flagged), NaN where not tested.
CONTACT_CHANNELS = (("px", "m", "Position"), ("py", "m", "Position"), ("pz", "m", "Position"),
                    ("nx", "1", "Normal"), ("ny", "1", "Normal"), ("nz", "1", "Normal"),
                    ("fx", "N", "Force"), ("fy", "N", "Force"), ("fz", "N", "Force"),
                    ("torsion", "N*m", "Torque"), ("valid", "1", "Valid"), ("single", "1", "SingleContact"))
#: Channels of ``pito-contacts``: six faces of ``len(CONTACT_CHANNELS)``.
CONTACT_CHANNEL_COUNT = 6 * len(CONTACT_CHANNELS)
#: Per face, the 6 channels of ``pito-wrenches``.
WRENCH_CHANNELS = (("fx", "N", "Force"), ("fy", "N", "Force"), ("fz", "N", "Force"),
                   ("tx", "N*m", "Torque"), ("ty", "N*m", "Torque"), ("tz", "N*m", "Torque"))
