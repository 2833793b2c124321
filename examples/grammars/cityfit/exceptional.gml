% CityFit's grammar problem 4 (Hohmann et al. 2009, §4, Fig. 11d): exceptional elements.
%
% A regular sixties facade is two rules: floors, then window tiles.  One blind window in the
% grid breaks that: naively every superordinate level (the floor holding it, the facade
% choosing that floor) needs a rule of its own.  Here the regular procedures stay, and the tile
% is located by its number instead (an instance locator in the spirit of Lipp et al. 2008): the
% variable tile counts the tiles as the program meets them, row by row from the bottom left
% (a split's first part is on top, so floors run bottom up and tiles left to right), and
% `WindowColumn` compares it with blind-window (`eq … ifelse`).  Changing that one variable moves
% the blind window.
%
% Run on a facade rectangle: derive_gml(path, scope=Scope(0, eye, (10, 9, 0))).
ShapeGrammar.Tools.init

3 !floor-height
2.5 !tile-width
1.2 !window-width
1.5 !window-height
% the number of the exceptional tile: row by row from the bottom left, starting at 0
6 !blind-window
0 !tile

/Wall { (0.85,0.78,0.66) color /wall label terminal-box } def
/Window { (0.44,0.56,0.66) color /window label terminal-box } def
/BlindWindow { (0.78,0.72,0.60) color /blind label terminal-box } def
% s WindowColumn -> : wall, the opening, wall; the opening is the blind window where the tile
% number is blind-window, else a window
/WindowColumn {
  [ -1 :window-height 0.6 ] /Y split
  Wall :tile :blind-window eq { BlindWindow } { Window } ifelse Wall
} def
% s Tile -> : wall | window column | wall, then the next tile number
/Tile { [ -1 :window-width -1 ] /X split Wall WindowColumn Wall :tile 1 add !tile } def
/Floor { :tile-width /X subdivide { Tile } repeat } def
/Facade { :floor-height /Y subdivide { Floor } repeat } def
Facade
finish
