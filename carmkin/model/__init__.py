"""What the machine is: parameters, the DH chain and its closed-form FK, motorized table joints, the eq. 4.7
singular cases and :class:`~carmkin.model.system.CArmSystem`, the one source of truth (numpy only), and the
URDF and Pinocchio models generated from it (``urdf.py``: xacro and Pinocchio, loaded on first use by
``system.urdf()`` / ``system.pinocchio()``)."""
