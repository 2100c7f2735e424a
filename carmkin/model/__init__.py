"""What the machine is (numpy only): parameters, the DH chain and its closed-form FK, motorized table joints,
the eq. 4.7 singular cases and :class:`~carmkin.model.system.CArmSystem`, the one source of truth."""
