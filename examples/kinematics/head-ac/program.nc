(5-axis head: a few 5-axis moves in nominal axis positions)
N10 G90 G21 G17
N20 G0 X0 Y0 Z100 A0 C0 ; start above the part, tool vertical
N30 G1 X50 Y20 Z50 A30 C45 F1000
N40 X60 (modal: only X changes nominally)
N50 G1 A-45.5 C-120 Z20
N60 M30
