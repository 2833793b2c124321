% CityFit's grammar problem 2 (Hohmann et al. 2009, §4, Fig. 11c): split order.
%
% Floors (horizontal) and window axes or a resalit (vertical) cross each other: which way to
% split first?  Split into floors first, the resalit stepping out of the facade would be cut
% into one piece per floor.  Following the paper, the order of the procedures here splits
% vertically first: left wing | resalit | right wing (`/X split Wing Resalit Wing`).  The
% resalit is one scope spanning all floors; `move` puts it resalit-depth out of the facade and
% it is split into floors inside; the wings are split into the same floors around it (the
% same `subdivide` by floor-height, so the floors line up).
%
% Run on a facade rectangle: derive_gml(path, scope=Scope(0, eye, (15, 9, 0))).
ShapeGrammar.Tools.init

3 !floor-height
2.5 !tile-width
5 !resalit-width
0.4 !resalit-depth
1.2 !window-width
1.5 !window-height

/Wall { (0.85,0.78,0.66) color /wall label terminal-box } def
/Window { (0.44,0.56,0.66) color /window label terminal-box } def
/WindowColumn { [ -1 :window-height 0.6 ] /Y split Wall Window Wall } def
/Tile { [ -1 :window-width -1 ] /X split Wall WindowColumn Wall } def
/Floor { :tile-width /X subdivide { Tile } repeat } def
/ResalitFloor { :tile-width /X subdivide { Tile } repeat } def
/Wing { :floor-height /Y subdivide { Floor } repeat } def
% the superordinate structure first: one scope from the ground to the top
/Resalit {
  0 0 :resalit-depth vector3 move
  :floor-height /Y subdivide { ResalitFloor } repeat
} def
/Facade { [ -1 :resalit-width -1 ] /X split Wing Resalit Wing } def
Facade
finish
