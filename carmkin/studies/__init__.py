"""Applications of the chain: the 5- vs 6-DOF workspace study (§4.6.1) and the multi-DOF table study."""
