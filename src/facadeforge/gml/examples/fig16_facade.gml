% Hohmann et al. 2009, Fig. 16: the GML shape grammar of a facade in Jakoministrasse, Graz
% (Fig. 15).  The paper prints only the three facade rules; the domain words they use, the
% first-floor rules and the top level are this file's own (documented in docs/gml.md).
% Coordinates: x along the facade, y up, z out of the facade (metres); the facade is a
% rectangle (depth 0), elements standing out of it are extruded.
ShapeGrammar.Tools.init

% ---------------------------------------------------------------- the library of domain words
/palette [ (0.93,0.86,0.70) (0.80,0.78,0.74) (0.55,0.50,0.45) (0.96,0.94,0.90) ] def
% s colour-index Paint -> s : a colour from the palette (index modulo its length)
/Paint { !ci :palette :ci :palette length mod get color } def
% s colour-index Wall -> : a piece of plain wall
/Wall { Paint /wall label terminal-box } def
% s depth colour-index Ledge -> : a ledge standing depth m out of the facade
/Ledge { !lc !ld :ld extrude :lc Paint /cornice label terminal-box } def
% s n colour-index left right Floor -> t1 ... tn n : a floor with wall strips left and right
% m wide at its sides and n equal window tiles between them (the first on top)
/Floor {
  !fr !fl !fc !fn
  [ :fl -1 :fr ] /X split :fc Wall exch :fc Wall
  :fn /X repeat
} def
% t width colour-index window below sill WindowTileSill -> sill window : a window tile, its
% window `width` m wide in the middle; vertically (relative) wall `below`, an absolute `sill`,
% the window and the rest of the tile as wall above.  Leaves the sill, then the window on top.
/WindowTileSill {
  !ts !tb !tw !tc !twidth
  [ -1 :twidth -1 ] /X split :tc Wall exch :tc Wall
  [ :tb :ts :tw -1 :tw sub :tb sub ] /Y split     % below sill window above, below on top
  :tc Wall 3 -1 roll :tc Wall                     % walls below and above
  exch
} def
% s Window -> : frame and glass
/Frame { 0.06 extrude 3 Paint /window label terminal-box } def
/Glass { (0.35,0.45,0.55) color /window label terminal-box } def
/Window { [ 0.06 -1 0.06 ] /X split Frame [ 0.06 -1 0.06 ] /Y split Frame Glass Frame Frame } def
% s WindowSill -> : a sill standing 0.12 m out of the facade
/WindowSill { 0.12 extrude 1 Paint /sill label terminal-box } def
% first floor: shop windows, the centre with the entrance
/Shop { [ 0.4 -1 0.3 ] /Y split 1 Wall (0.30,0.35,0.40) color /shop label terminal-box 1 Wall } def
/Door { [ -1 0.5 ] /Y split (0.35,0.25,0.15) color /door label terminal-box 1 Wall } def
/ShopTile { [ -1 -6 -1 ] /X split 1 Wall Shop 1 Wall } def
/FirstFloorRight { [ -1 -1 0.5 ] /X split ShopTile ShopTile 1 Wall } def
/FirstFloorLeft { [ 0.5 -1 -1 ] /X split 1 Wall ShopTile ShopTile } def
/FirstFloorCenter { [ -1 1.4 -1 ] /X split 1 Wall Door 1 Wall } def

% ---------------------------------------------------------------- Fig. 16 as printed
% (the letters b, c, d before the Floor lines label dimensions in Fig. 15: comments here)
1.2 !window-width
16 !wall-colour
/RightFacade {
  [2.85 0.15 3.0 3.0] /Y split-r
  FirstFloorRight
  0.15 3 Ledge
  % d
  2 :wall-colour 0 0.5 Floor { :window-width :wall-colour -0.625 -0.125 0.04 WindowTileSill Window WindowSill } repeat
  2 :wall-colour 0 0.5 Floor { :window-width :wall-colour -0.625 -0.125 0.04 WindowTileSill Window WindowSill } repeat
} def
/CenterFacade {
  [2.85 0.15 3.0 3.0] /Y split-r
  FirstFloorCenter
  0.15 3 Ledge
  % c
  1 :wall-colour 0 0 Floor { :window-width :wall-colour -0.625 -0.125 0.04 WindowTileSill Window WindowSill } repeat
  1 :wall-colour 0 0 Floor { :window-width :wall-colour -0.625 -0.125 0.04 WindowTileSill Window WindowSill } repeat
} def
/LeftFacade {
  [2.85 0.15 3.0 3.0] /Y split-r
  FirstFloorLeft
  0.15 3 Ledge
  % b
  2 :wall-colour 0.5 0 Floor { :window-width :wall-colour -0.625 -0.125 0.04 WindowTileSill Window WindowSill } repeat
  2 :wall-colour 0.5 0 Floor { :window-width :wall-colour -0.625 -0.125 0.04 WindowTileSill Window WindowSill } repeat
} def

% ---------------------------------------------------------------- the facade
/Facade { [ 4.5 2.4 4.5 ] /X split LeftFacade CenterFacade RightFacade } def
scope (11.4,9,0) scale Facade
finish
