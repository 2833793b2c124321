% CityFit's grammar problem 1 (Hohmann et al. 2009, §4, Fig. 11a): overlapping elements.
%
% A window sill is wider than its window: it reaches over the split line into the wall beside
% the window.  Split strictly, the wall next to the window would have to be split as well, in
% every tile.  In GML the sill slot is split once more ([ -1 ] /X split: one child, so the slot
% keeps its own scope), and that child is transformed beyond it: `scale` makes it
% (w + 2 overhang) / w times as wide, `move` shifts it by -overhang along x, `extrude` gives it
% its depth.  The tile's split wall | window | wall stays a partition; only the sill's geometry
% overlaps the neighbouring walls.
%
% Run on a facade rectangle: derive_gml(path, scope=Scope(0, eye, (10, 6, 0))).
ShapeGrammar.Tools.init

3 !floor-height
2.5 !tile-width
1.2 !window-width
1.5 !window-height
0.06 !sill-height
0.12 !sill-depth
0.15 !overhang

/Wall { (0.85,0.78,0.66) color /wall label terminal-box } def
/Window { (0.44,0.56,0.66) color /window label terminal-box } def
/Sill { (0.90,0.88,0.83) color /sill label terminal-box } def
% s SillWall -> : the sill slot is wall; its one child, widened and moved, is the sill
/SillWall {
  dup [ -1 ] /X split
  :window-width :overhang 2 mul add :window-width div 1 1 vector3 scale
  :overhang neg 0 0 vector3 move
  :sill-depth extrude Sill
  (0.85,0.78,0.66) color /wall label terminal-box
} def
% s WindowColumn -> : wall below, the sill slot, the window, wall above (bottom up)
/WindowColumn {
  [ -1 :sill-height :window-height 0.6 ] /Y split
  Wall SillWall Window Wall
} def
% s Tile -> : wall | window column | wall
/Tile { [ -1 :window-width -1 ] /X split Wall WindowColumn Wall } def
/Floor { :tile-width /X subdivide { Tile } repeat } def
/Facade { :floor-height /Y subdivide { Floor } repeat } def
Facade
finish
