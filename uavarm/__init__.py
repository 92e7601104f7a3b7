"""Host side of the uavarm toolchain: C build, link client, simulator, command line."""
