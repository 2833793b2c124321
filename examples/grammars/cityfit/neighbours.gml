% CityFit's grammar problem 3 (Hohmann et al. 2009, §4, Fig. 11b): unknown neighbours.
%
% A grammar is a tree: neighbouring grandchildren do not know of each other.  A main ledge cut
% by a prior-ranked resalit falls into three pieces (left wing, resalit, right wing) in three
% different subtrees; yet all pieces must stand out of their wall by the same depth, which has
% to be propagated from the top of the tree down to every terminal.  In GML the top rule
% binds it once, `!ledge-depth` (here from the facade width, read with `scope-size`), and the
% `Ledge` procedure reads it with `:ledge-depth` in every branch, so the pieces of the wings
% and the one on the resalit (which itself stands resalit-depth out) are extruded alike.
% Changing ledge-ratio (or the facade width) changes every piece at once.
%
% Run on a facade rectangle: derive_gml(path, scope=Scope(0, eye, (15, 9.3, 0))).
ShapeGrammar.Tools.init

3 !ground-height
0.3 !ledge-height
3 !floor-height
2.5 !tile-width
5 !resalit-width
0.4 !resalit-depth
1.2 !window-width
1.5 !window-height
0.02 !ledge-ratio

/Wall { (0.85,0.78,0.66) color /wall label terminal-box } def
/Window { (0.44,0.56,0.66) color /window label terminal-box } def
/WindowColumn { [ -1 :window-height 0.6 ] /Y split Wall Window Wall } def
/Tile { [ -1 :window-width -1 ] /X split Wall WindowColumn Wall } def
/Floor { :tile-width /X subdivide { Tile } repeat } def
% s Ledge -> : a piece of the main ledge, as deep as the top rule said
/Ledge { :ledge-depth extrude (0.94,0.91,0.86) color /cornice label terminal-box } def
% s Storeys -> : ground floor, the main ledge, upper floors (the same in wings and resalit)
/Storeys {
  [ :ground-height :ledge-height -1 ] /Y split
  Floor Ledge
  :floor-height /Y subdivide { Floor } repeat
} def
/Wing { Storeys } def
/Resalit { 0 0 :resalit-depth vector3 move Storeys } def
% the top of the tree: the ledge depth is bound here, once
/Facade {
  scope-size getx :ledge-ratio mul !ledge-depth
  [ -1 :resalit-width -1 ] /X split Wing Resalit Wing
} def
Facade
finish
