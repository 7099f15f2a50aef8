"""Robot control: the servo loop, the Cartesian controller, palpation and safety."""
