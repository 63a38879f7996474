"""bridge: MAVLink mission upload/download and the mock autopilot. Knows missions, not grids. Filled by issue 5."""
