% Hohmann et al. 2009, Fig. 14: an arch out of a box.  The wall's upper part (above the
% springing line) is cut into n convex wedges by planes through the arch centre; each wedge is
% cut by the chord of its stretch of the arch into the stone (a voussoir with the wall beside
% it) and the void below the chord.  Every piece is a convex polyhedron: no special cases.
ShapeGrammar.Tools.init
3.0 !w  4.0 !h  0.3 !d      % wall width, height, depth (m)
2.0 !spring                 % height of the springing line
1.0 !r                      % arch radius: the opening is 2 r wide, centred
6 !n                        % number of voussoirs
:w 2 div :spring 0 vector3 !c

/Stone { /wall label terminal-box } def
/Voussoir { /molding label terminal-box } def
/Hole { terminal-void } def

% angle (degrees) -> the point on the arch at that angle
/ArchPoint { !t :t cos :r mul :t sin :r mul 0 vector3 :c add } def
% angle -> the plane through the centre along that ray; inside: the angles above it
/Ray { !t :c :t cos :t sin 0 vector3 :c add :c (0,0,1) add cp-plane } def

/Lower { [ -1 2 :r mul -1 ] /X split Stone Hole Stone } def

% piece k -> : the wedge between angles k*180/n and (k+1)*180/n, cut by its chord
/Wedge {
  !k
  :k 180 mul :n div ArchPoint !a
  :k 1 add 180 mul :n div ArchPoint !b
  :a :b :a (0,0,1) add cp-plane split-plane Hole Voussoir
} def

/Upper {
  0 1 :n 2 sub {                          % rest i
    !i
    :i 1 add 180 mul :n div Ray split-plane % piece rest
    exch :i Wedge                           % rest
  } for
  :n 1 sub Wedge                          % the last wedge is what is left
} def

scope :w :h :d vector3 scale
[ :spring -1 ] /Y split Lower Upper
finish
