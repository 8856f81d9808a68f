"""Machine programs: the one G-code emitter (:mod:`.program`) and what it writes,
a flat plate's grooves (:mod:`.gcode`), a curved host's paths
(:mod:`.surface_gcode`), a probe grid and a levelled program (:mod:`.leveling`);
reading a program back (:mod:`.gcode_reader`); the cutting order (:mod:`.order`)
and the time on a machine (:mod:`.timing`, :mod:`.machines`)."""
